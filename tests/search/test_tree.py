"""Tree mechanics: nodes merge by state, children are added once, Q is the incremental mean."""

from __future__ import annotations

import dataclasses

import pytest

from stalm.domain.outcome import Outcome
from stalm.search.tree import Edge, SearchTree
from tests.search.synthetic import drawn, move, state


def feasible(target: str, reward: float) -> Outcome:
    return Outcome(state(target), reward, True, None, False)


def test_root_registers_its_actions() -> None:
    tree = SearchTree(state("s0"), [move("a"), move("b")])
    view = tree.node(state("s0"))
    assert [c.action for c in view.children] == [move("a"), move("b")]
    assert all((c.n, c.q, c.children) == (0, 0.0, ()) for c in view.children)
    assert state("s0") in tree
    assert len(tree) == 1


def test_nodes_and_children_are_added_once() -> None:
    tree = SearchTree(state("s0"), [move("a")])
    assert not tree.add_node(state("s0"), [move("zzz")])
    assert [c.action for c in tree.node(state("s0")).children] == [move("a")]
    assert tree.add_action(state("s0"), move("illegal"))
    assert not tree.add_action(state("s0"), move("illegal"))
    kappa = drawn("a", 1)
    assert tree.add_kappa(state("s0"), move("a"), kappa, feasible("s1", 3.0))
    assert not tree.add_kappa(state("s0"), move("a"), kappa, feasible("elsewhere", 99.0))
    assert tree.outcome(Edge(state("s0"), move("a"), kappa)) == feasible("s1", 3.0)


def test_q_is_the_incremental_mean_of_returns() -> None:
    root = state("s0")
    tree = SearchTree(root, [move("a")])
    k1, k2 = drawn("a", 1), drawn("a", 2)
    tree.add_kappa(root, move("a"), k1, feasible("s1", 3.0))
    tree.add_kappa(root, move("a"), k2, feasible("s2", 1.0))
    # G = r + γ·tail with γ = 0.5: k1 gets 3 + 5 = 8, 3 + 0 = 3, 3 + 2 = 5; k2 gets 1 + 10 = 11
    assert tree.backup([Edge(root, move("a"), k1)], 10.0, gamma=0.5) == (8.0,)
    assert tree.backup([Edge(root, move("a"), k1)], 0.0, gamma=0.5) == (3.0,)
    assert tree.backup([Edge(root, move("a"), k1)], 4.0, gamma=0.5) == (5.0,)
    assert tree.backup([Edge(root, move("a"), k2)], 20.0, gamma=0.5) == (11.0,)
    view = tree.node(root)
    cont = view.child(move("a"))
    assert cont.child(k1).n == 3
    assert cont.child(k1).q == pytest.approx((8.0 + 3.0 + 5.0) / 3)  # 5.333...
    assert cont.child(k2).q == pytest.approx(11.0)
    assert (cont.n, cont.q) == (4, pytest.approx((8.0 + 3.0 + 5.0 + 11.0) / 4))  # 6.75
    assert view.n == 4


def test_backup_along_a_path_discounts_each_edge() -> None:
    s0, s1 = state("s0"), state("s1")
    tree = SearchTree(s0, [move("a")])
    tree.add_kappa(s0, move("a"), drawn("a", 0), feasible("s1", 0.0))
    tree.add_node(s1, [move("b")])
    tree.add_kappa(s1, move("b"), drawn("b", 0), feasible("s2", 3.0))
    tree.add_node(state("s2"), [])
    path = [Edge(s0, move("a"), drawn("a", 0)), Edge(s1, move("b"), drawn("b", 0))]
    # tail 100 at s2: G_b = 3 + 0.99·100 = 102, G_a = 0 + 0.99·102 = 100.98
    returns = tree.backup(path, 100.0, gamma=0.99, leaf=state("s2"))
    assert returns == pytest.approx((100.98, 102.0))
    assert [tree.visits(s) for s in (s0, s1, state("s2"))] == [1, 1, 1]
    assert tree.node(s1).child(move("b")).q == pytest.approx(102.0)
    assert tree.node(s0).child(move("a")).q == pytest.approx(100.98)


def test_views_are_frozen_copies() -> None:
    root = state("s0")
    tree = SearchTree(root, [move("a")])
    view = tree.node(root)
    with pytest.raises(dataclasses.FrozenInstanceError):
        view.n = 5  # type: ignore[misc]
    tree.add_kappa(root, move("a"), drawn("a", 0), feasible("s1", 1.0))
    tree.backup([Edge(root, move("a"), drawn("a", 0))], 0.0, gamma=0.99)
    assert view.n == 0  # the old copy does not change
    assert tree.node(root).n == 1
    stats = tree.stats()
    assert (stats.discrete_nodes, stats.continuous_nodes, stats.kappa_children) == (1, 1, 1)
    assert (stats.infeasible_children, stats.root_visits) == (0, 1)


def test_a_subtree_keeps_the_statistics_of_every_node_the_new_root_reaches() -> None:
    """Tree reuse: after executing s0 -a-> s1, s1's subtree is kept with its N and Q as they
    were; the old root and the sibling branch it alone reached are dropped."""
    s0, s1, s2, s3, s4 = (state(name) for name in ("s0", "s1", "s2", "s3", "s4"))
    tree = SearchTree(s0, [move("a"), move("b")])
    ka, kb = drawn("a", 1), drawn("b", 1)
    tree.add_kappa(s0, move("a"), ka, feasible("s1", 3.0))
    tree.add_kappa(s0, move("b"), kb, feasible("s2", 0.0))
    tree.add_node(s1, [move("c"), move("back")])
    tree.add_node(s2, [move("d")])
    kc, kback = drawn("c", 1), drawn("back", 1)
    tree.add_kappa(s1, move("c"), kc, feasible("s3", 1.0))
    tree.add_kappa(s1, move("back"), kback, feasible("s0", 0.0))  # a cycle back to the root
    tree.add_node(s3, [move("e")])
    tree.add_kappa(s2, move("d"), drawn("d", 1), feasible("s4", 5.0))
    tree.add_node(s4, [])
    tree.backup([Edge(s0, move("a"), ka), Edge(s1, move("c"), kc)], 2.0, 0.5, s3)
    tree.backup([Edge(s0, move("a"), ka), Edge(s1, move("back"), kback)], 0.0, 0.5)
    tree.backup([Edge(s0, move("b"), kb), Edge(s2, move("d"), drawn("d", 1))], 0.0, 0.5, s4)
    before = {s: tree.node(s) for s in (s0, s1, s3)}

    reused = tree.subtree(s1)

    assert reused.root == s1
    # s0 is reachable from s1 (by 'back'), so it stays; s2 and s4 hang only off s0 -b->
    # and are reachable too through s0: everything reachable from s1 is kept
    assert set(reused.states()) == {s1, s3, s0, s2, s4}
    for s, view in before.items():
        assert reused.node(s) == view
    assert reused.visits(s1) == 2
    assert reused.node(s1).child(move("c")).q == pytest.approx(1.0 + 0.5 * 2.0)


def test_a_subtree_drops_what_the_new_root_cannot_reach() -> None:
    s0, s1, s2 = state("s0"), state("s1"), state("s2")
    tree = SearchTree(s0, [move("a"), move("b")])
    ka, kb = drawn("a", 1), drawn("b", 1)
    tree.add_kappa(s0, move("a"), ka, feasible("s1", 0.0))
    tree.add_kappa(s0, move("b"), kb, feasible("s2", 0.0))
    tree.add_node(s1, [move("c")])
    tree.add_node(s2, [move("d")])
    tree.backup([Edge(s0, move("a"), ka)], 4.0, 1.0, s1)
    reused = tree.subtree(s1)
    assert list(reused.states()) == [s1]
    assert reused.node(s1) == tree.node(s1)
    assert s0 not in reused and s2 not in reused
    with pytest.raises(KeyError):
        tree.subtree(state("nowhere"))
