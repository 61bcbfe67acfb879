"""Selection, widening, rollout and final-choice policies on hand-set numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stalm.domain.outcome import Infeasibility, Outcome
from stalm.search.policies import (
    ProgressiveWidening,
    RolloutValue,
    SearchPolicies,
    UCTSelection,
    argmax_random_tie,
    best_by_q,
    rollout,
)
from stalm.search.settings import SearchSettings
from stalm.search.transition import Kappa
from stalm.search.tree import ChildStats, Edge, SearchTree
from stalm.search.uct import simulate
from tests.search.synthetic import FreshKappaMDP, drawn, move, state, warm_chain

# ------------------------------------------------------------------------------ UCT


def stats(q: tuple[float, ...], n: tuple[int, ...], parent: int) -> ChildStats:
    return ChildStats(state("s0"), tuple(range(len(q))), q, n, parent)


def test_uct_scores_by_hand() -> None:
    # parent 4 visits: ln(4 + 1) = 1.6094379; children (Q, n) = (1, 3), (2, 1), (0.5, 0)
    hand = stats((1.0, 2.0, 0.5), (3, 1, 0), parent=4)
    # c = 1: 1 + sqrt(ln5/4) = 1.6343181, 2 + sqrt(ln5/2) = 2.8970613, 0.5 + sqrt(ln5) = 1.7686362
    assert UCTSelection(1.0).scores(hand) == pytest.approx([1.6343181, 2.8970613, 1.7686362])
    assert UCTSelection(1.0)(hand, np.random.default_rng(0)) == 1
    # c = 5: 4.1715906, 6.4853064, 6.8431812 -> the unvisited child wins
    assert UCTSelection(5.0).scores(hand) == pytest.approx([4.1715906, 6.4853064, 6.8431812])
    assert UCTSelection(5.0)(hand, np.random.default_rng(0)) == 2


def test_unvisited_child_gets_no_infinite_bonus() -> None:
    # Q = 10 after 5 visits: 10 + sqrt(ln6/6) = 10.5464674 beats 0 + sqrt(ln6) = 1.3385662
    hand = stats((10.0, 0.0), (5, 0), parent=5)
    assert UCTSelection(1.0).scores(hand) == pytest.approx([10.5464674, 1.3385662])
    assert UCTSelection(1.0)(hand, np.random.default_rng(0)) == 0


def test_first_visit_is_a_uniform_tie_decided_by_the_seed() -> None:
    # N_parent = 0: ln(1) = 0, every score is Q = 0 -> a three-way tie
    fresh = stats((0.0, 0.0, 0.0), (0, 0, 0), parent=0)
    for seed in range(20):
        expected = int(np.random.default_rng(seed).integers(3))
        assert UCTSelection(50.0)(fresh, np.random.default_rng(seed)) == expected
    chosen = {UCTSelection(50.0)(fresh, np.random.default_rng(seed)) for seed in range(50)}
    assert chosen == {0, 1, 2}


def test_ties_only_among_the_best() -> None:
    partial = stats((1.0, 1.0, 0.0), (2, 2, 2), parent=6)
    chosen = {UCTSelection(50.0)(partial, np.random.default_rng(seed)) for seed in range(50)}
    assert chosen == {0, 1}


def test_no_tie_leaves_the_random_stream_alone() -> None:
    rng = np.random.default_rng(7)
    assert argmax_random_tie(np.array([0.0, 2.0, 1.0]), rng) == 1
    assert rng.integers(1 << 30) == np.random.default_rng(7).integers(1 << 30)


# ------------------------------------------------------------------------------ widening


def first_visit_count_allowing(children: int, k: float, alpha: float) -> int:
    """The smallest N with children <= k·N^α, from the formula: N >= (children / k)^(1/α)."""
    return math.ceil((children / k) ** (1.0 / alpha))


def test_widening_thresholds_from_the_formula() -> None:
    k, alpha = 1.5, 0.15
    # (m / 1.5)^(1 / 0.15) for m = 0..4: 0, 0.067, 6.807, 101.594, 691.499
    thresholds = [first_visit_count_allowing(m, k, alpha) for m in range(5)]
    assert thresholds == [0, 1, 7, 102, 692]
    widen = ProgressiveWidening(k, alpha)
    for m, n in enumerate(thresholds):
        assert widen(m, n)
        if n > 0:
            assert not widen(m, n - 1)


def test_widening_count_in_the_tree() -> None:
    # every draw is a new κ; horizon 1 ends each simulation after the root's action
    settings = SearchSettings(horizon=1)
    fake = FreshKappaMDP()
    tree = SearchTree.for_root(fake.as_mdp(), state("s0"))
    policies = SearchPolicies.from_settings(settings)
    rng = np.random.default_rng(0)
    counts = []
    for _ in range(150):
        simulate(tree, fake.as_mdp(), rng, depth0=0, gamma=0.99, horizon=1, policies=policies)
        counts.append(tree.num_kappas(state("s0"), move("a")))
    # children after the simulation that found the node with N earlier visits
    expected = [1] + [2] * 6 + [3] * 95 + [4] * 48
    assert counts == expected
    assert fake.draws == 4


# ------------------------------------------------------------------------------ rollout


def test_rollout_discounts_once() -> None:
    mdp = warm_chain()
    rng = np.random.default_rng(0)
    # s2 has the one action c: 100 at the goal, first reward undiscounted
    from_s2 = rollout(mdp.as_mdp(), state("s2"), 2, rng, gamma=0.99, horizon=20)
    assert from_s2.value == pytest.approx(100.0)
    assert from_s2.end == "goal"
    assert from_s2.actions == (drawn("c", 0),)


def test_rollout_stops_at_the_horizon_and_at_infeasible() -> None:
    mdp = warm_chain()
    # from s1 at depth 19 with H = 20: one action; b gives 3, x gives -6 (then stops)
    values = set()
    for seed in range(20):
        result = rollout(
            mdp.as_mdp(), state("s1"), 19, np.random.default_rng(seed), gamma=0.99, horizon=20
        )
        assert result.steps == 1
        values.add((result.value, result.end))
    assert values == {(3.0, "horizon"), (-6.0, "infeasible")}
    # from s0 with H = 2: a (0) then b (3, discounted once: 2.97) or x (-5.94)
    returns = {
        round(
            rollout(
                mdp.as_mdp(), state("s0"), 0, np.random.default_rng(s), gamma=0.99, horizon=2
            ).value,
            9,
        )
        for s in range(40)
    }
    assert returns == {2.97, -5.94, -6.0}


def test_rollout_value_hands_back_a_goal_plan() -> None:
    value = RolloutValue(gamma=0.99, horizon=20)
    leaf = value(warm_chain().as_mdp(), state("s2"), 2, np.random.default_rng(0))
    assert leaf.value == pytest.approx(100.0)
    assert leaf.goal_plan == (drawn("c", 0),)


# ------------------------------------------------------------------------------ final choice


def outcome(reward: float = 0.0, feasible: bool = True) -> Outcome:
    failure = None if feasible else Infeasibility("no_ik", "hand-made")
    return Outcome(state("s1"), reward, feasible, failure, False)


def test_best_by_q_on_hand_set_statistics() -> None:
    root = state("s0")
    tree = SearchTree(root, [move("a"), move("b"), move("c")])
    a1, b1, b2, c1 = drawn("a", 1), drawn("b", 1), drawn("b", 2), drawn("c", 1)
    for action, kappa, reward in [("a", a1, 6.0), ("b", b1, 0.0), ("b", b2, 6.0)]:
        tree.add_kappa(root, move(action), kappa, outcome(reward))
    # an infeasible κ with a (hand-made) high reward must never be recommended
    blocked = Infeasibility("no_ik", "blocked")
    tree.add_kappa(root, move("c"), blocked, outcome(50.0, feasible=False))
    tree.add_kappa(root, move("c"), c1, outcome(0.0))
    visits: list[tuple[str, Kappa, float]] = [
        ("a", a1, 0.0),  # a: Q 6, n 2
        ("a", a1, 0.0),
        ("b", b1, 9.0),  # b1: returns 9, 3 -> Q 6, n 2
        ("b", b1, 3.0),
        ("b", b2, 0.0),  # b2: return 6 -> Q 6, n 1; b: Q 6, n 3
        ("c", blocked, 0.0),  # c: returns 50, 1 -> Q 25.5 but only c1 (Q 1) is feasible
        ("c", c1, 1.0),
    ]
    for action, key, tail in visits:
        tree.backup([Edge(root, move(action), key)], tail, gamma=1.0)
    view = tree.node(root)
    assert [(c.q, c.n) for c in view.children] == [(6.0, 2), (6.0, 3), (25.5, 2)]
    choice = best_by_q(view)
    assert choice is not None
    # c has the highest Q (25.5) and a feasible κ child
    assert choice[0].action == move("c")
    assert choice[1].kappa == c1
    # without c: a and b tie on Q = 6; b has more visits; b1 and b2 tie, b1 has more visits
    tree2 = SearchTree(root, [move("a"), move("b")])
    for action, kappa, reward in [("a", a1, 6.0), ("b", b1, 0.0), ("b", b2, 6.0)]:
        tree2.add_kappa(root, move(action), kappa, outcome(reward))
    for action, kappa, tail in [
        ("a", a1, 0.0),
        ("a", a1, 0.0),
        ("b", b1, 9.0),
        ("b", b1, 3.0),
        ("b", b2, 0.0),
    ]:
        tree2.backup([Edge(root, move(action), kappa)], tail, gamma=1.0)
    choice2 = best_by_q(tree2.node(root))
    assert choice2 is not None
    assert (choice2[0].action, choice2[1].kappa) == (move("b"), b1)


def test_best_by_q_none_without_a_feasible_child() -> None:
    root = state("s0")
    tree = SearchTree(root, [move("a")])
    assert best_by_q(tree.node(root)) is None
    why = Infeasibility("no_ik", "blocked")
    tree.add_kappa(root, move("a"), why, outcome(-6.0, feasible=False))
    tree.backup([Edge(root, move("a"), why)], 0.0, gamma=0.99)
    assert best_by_q(tree.node(root)) is None
