"""WarmUpTree (Algorithm 4, **Ours**): values backed up exactly as a simulation does.

MDP (``warm_chain``): s0 -a-> s1 -b-> s2 -c-> s3 = goal with rewards 0, 3, 100; w at s0 and
x at s1 are never feasible (-6). γ = 0.99. Every expected number below is worked out by hand.

Golden file: ``golden/warmup_chain.json`` is the tree after warming up with three plans.
Regenerate it with ``STALM_UPDATE_GOLDEN=1 pytest tests/search`` after an intended change,
and review the diff.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from stalm.domain.outcome import Infeasibility
from stalm.search.concretize import concretize
from stalm.search.policies import RolloutValue
from stalm.search.tree import SearchTree
from stalm.search.warmup import WarmedPlan, add_plan, warm_up_tree
from tests.search.synthetic import GraphMDP, describe, drawn, move, plan, state, warm_chain

GOLDEN = Path(__file__).parent / "golden" / "warmup_chain.json"
GAMMA = 0.99


def warmed(
    mdp: GraphMDP, *plans: tuple[str, ...], horizon: int = 20, depth0: int = 0
) -> tuple[SearchTree, tuple[WarmedPlan, ...]]:
    rng = np.random.default_rng(0)
    concrete = concretize(
        mdp.as_mdp(),
        state("s0"),
        [plan(*names) for names in plans],
        rng,
        depth0=depth0,
        horizon=horizon,
    )
    tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
    added = warm_up_tree(
        tree,
        mdp.as_mdp(),
        concrete.plans,
        rng,
        depth0=depth0,
        gamma=GAMMA,
        horizon=horizon,
        value=RolloutValue(GAMMA, horizon),
    )
    return tree, added


def test_three_plans_by_hand() -> None:
    tree, added = warmed(warm_chain(), ("w",), ("a", "x"), ("a", "b"))
    # [w]: infeasible at once -> G = -6
    assert added[0].returns == (-6.0,)
    # [a, x]: x infeasible -> G_x = -6, G_a = 0 + 0.99·(-6) = -5.94
    assert added[1].returns == pytest.approx((-5.94, -6.0))
    # [a, b]: leaf s2, rollout from s2 = 100 (c reaches the goal) ->
    #   G_b = 3 + 0.99·100 = 102, G_a = 0 + 0.99·102 = 100.98
    assert added[2].returns == pytest.approx((100.98, 102.0))
    # the rollout reached the goal: the plan to it is handed back
    assert added[2].goal_plan == (drawn("a", 0), drawn("b", 0), drawn("c", 0))

    root = tree.node(state("s0"))
    assert root.n == 3  # one visit per plan, root included
    a = root.child(move("a"))
    assert (a.n, a.q) == (2, pytest.approx((-5.94 + 100.98) / 2))  # 47.52
    assert a.child(drawn("a", 0)).q == pytest.approx(47.52)
    w = root.child(move("w"))
    assert (w.n, w.q) == (1, -6.0)
    (w_kappa,) = w.children
    assert isinstance(w_kappa.kappa, Infeasibility)
    assert not w_kappa.outcome.feasible

    s1 = tree.node(state("s1"))
    assert s1.n == 2
    assert (s1.child(move("x")).n, s1.child(move("x")).q) == (1, -6.0)
    assert (s1.child(move("b")).n, s1.child(move("b")).q) == (1, pytest.approx(102.0))
    s2 = tree.node(state("s2"))
    assert s2.n == 1  # the leaf's visit
    assert [(c.action, c.n, c.q) for c in s2.children] == [(move("c"), 0, 0.0)]
    assert state("s3") not in tree


def test_a_plan_reaching_the_goal_is_valued_by_its_rewards() -> None:
    tree, added = warmed(warm_chain(), ("a", "b", "c"))
    # terminal at the goal: G_c = 100, G_b = 3 + 99 = 102, G_a = 100.98; no rollout
    assert added[0].returns == pytest.approx((100.98, 102.0, 100.0))
    assert added[0].goal_plan == (drawn("a", 0), drawn("b", 0), drawn("c", 0))
    assert state("s3") not in tree  # a terminal arrival makes no node


@pytest.mark.parametrize(("depth0", "horizon"), [(0, 2), (3, 5)])
def test_a_plan_cut_by_the_horizon_is_terminal(depth0: int, horizon: int) -> None:
    tree, added = warmed(warm_chain(), ("a", "b"), horizon=horizon, depth0=depth0)
    # b is the last step allowed: G_b = 3, G_a = 0.99·3 = 2.97; no rollout, no s2 node
    assert added[0].returns == pytest.approx((2.97, 3.0))
    assert added[0].goal_plan is None
    assert state("s2") not in tree


def test_an_illegal_step_enters_the_tree_as_an_infeasible_child() -> None:
    mdp = warm_chain()
    tree, added = warmed(mdp, ("b",))
    assert added[0].returns == (-6.0,)
    b = tree.node(state("s0")).child(move("b"))  # not legal at s0, registered anyway
    (child,) = b.children
    assert isinstance(child.kappa, Infeasibility)
    assert child.kappa.kind == "precondition"
    assert (b.n, b.q, child.n, child.q) == (1, -6.0, 1, -6.0)


def test_warm_up_reuses_t_outcomes_and_stops_at_a_goal() -> None:
    mdp = warm_chain()
    rng = np.random.default_rng(0)
    concrete = concretize(mdp.as_mdp(), state("s0"), [plan("a", "b", "c"), plan("w")], rng).plans
    steps_before = mdp.calls["step"]
    tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
    added = warm_up_tree(
        tree,
        mdp.as_mdp(),
        concrete,
        rng,
        depth0=0,
        gamma=GAMMA,
        horizon=20,
        value=RolloutValue(GAMMA, 20),
    )
    assert mdp.calls["step"] == steps_before  # T is not paid again
    assert len(added) == 1


def test_a_plan_from_another_state_is_refused() -> None:
    mdp = warm_chain()
    rng = np.random.default_rng(0)
    (elsewhere,) = concretize(mdp.as_mdp(), state("s1"), [plan("b")], rng).plans
    tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
    with pytest.raises(ValueError, match="another state"):
        add_plan(
            tree,
            mdp.as_mdp(),
            elsewhere,
            rng,
            depth0=0,
            gamma=GAMMA,
            horizon=20,
            value=RolloutValue(GAMMA, 20),
        )


def test_golden_tree() -> None:
    tree, _ = warmed(warm_chain(), ("w",), ("a", "x"), ("a", "b"))
    snapshot = tree.snapshot(describe)
    if os.environ.get("STALM_UPDATE_GOLDEN"):
        GOLDEN.write_text(json.dumps(snapshot, indent=2) + "\n")
    assert snapshot == json.loads(GOLDEN.read_text())


def test_a_passed_deadline_stops_the_warm_up_before_the_next_plan() -> None:
    mdp = warm_chain()
    rng = np.random.default_rng(0)
    concrete = concretize(mdp.as_mdp(), state("s0"), [plan("w"), plan("a", "x")], rng, horizon=20)
    tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
    kwargs = {"depth0": 0, "gamma": GAMMA, "horizon": 20, "value": RolloutValue(GAMMA, 20)}
    assert warm_up_tree(tree, mdp.as_mdp(), concrete.plans, rng, deadline=0.0, **kwargs) == ()
    assert tree.node(state("s0")).n == 0  # nothing was added
    added = warm_up_tree(tree, mdp.as_mdp(), concrete.plans, rng, deadline=None, **kwargs)
    assert len(added) == 2
