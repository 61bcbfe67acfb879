"""Simulate (Algorithm 5) and WarmStartedUCT (Algorithm 3) on synthetic MDPs."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from stalm.domain.outcome import Infeasibility
from stalm.search.concretize import concretize
from stalm.search.policies import SearchPolicies, StateValue
from stalm.search.settings import SearchSettings
from stalm.search.tree import SearchTree
from stalm.search.uct import simulate, warm_started_uct
from stalm.search.warmup import warm_up_tree
from tests.search.synthetic import (
    GraphMDP,
    Option,
    det,
    detour,
    drawn,
    graph,
    move,
    plan,
    replay,
    state,
    warm_chain,
)


def loop() -> GraphMDP:
    """s0 -a-> s1 -b-> s0 forever, reward 1 per step, no goal; one κ per edge."""
    return graph([("s0", "a", det("s1", 1.0)), ("s1", "b", det("s0", 1.0))])


def zero_value(settings: SearchSettings) -> SearchPolicies:
    """STaLM's policies with V = 0 instead of rollouts (so T is paid only inside the tree)."""
    return dataclasses.replace(
        SearchPolicies.from_settings(settings), value=StateValue(lambda s, d: 0.0)
    )


def test_wrong_warm_plan_then_search_finds_the_goal() -> None:
    mdp = detour()
    settings = SearchSettings()
    rng = np.random.default_rng(3)
    concrete = concretize(mdp.as_mdp(), state("s0"), [plan("a", "b", "c")], rng)
    (wrong,) = concrete.plans
    assert (wrong.failure, wrong.failed_step) == ("lack_of_3d_understanding", 2)

    tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
    warm_up_tree(
        tree,
        mdp.as_mdp(),
        concrete.plans,
        rng,
        depth0=0,
        gamma=settings.gamma,
        horizon=settings.horizon,
        value=SearchPolicies.from_settings(settings).value,
    )
    # the tree holds the plan's first k = 3 steps, the last one as an infeasible child
    a_kappa, b_kappa, c_kappa = (step.kappa for step in wrong.steps)
    assert tree.node(state("s0")).child(move("a")).child(a_kappa).n == 1
    assert tree.node(state("s1")).child(move("b")).child(b_kappa).n == 1
    c_child = tree.node(state("s2")).child(move("c")).child(c_kappa)
    assert isinstance(c_kappa, Infeasibility)
    assert (c_child.n, c_child.q) == (1, -6.0)
    # G_c = -6, G_b = 3 + 0.99·(-6) = -2.94, G_a = 0.99·(-2.94) = -2.9106
    assert tree.node(state("s0")).child(move("a")).q == pytest.approx(-2.9106)

    result = warm_started_uct(mdp.as_mdp(), state("s0"), (), rng, settings=settings, tree=tree)
    assert result.success and result.stop_reason == "goal"
    assert result.goal_plan is not None
    assert replay(mdp, "s0", result.goal_plan).goal_reached
    assert result.best_action == result.goal_plan[0]
    assert result.best_outcome is not None and result.best_outcome.feasible
    assert 1 <= result.counters.simulations <= settings.budget
    assert tree.node(state("s2")).child(move("c")).child(c_kappa).q == -6.0


@pytest.mark.parametrize("seed", range(5))
def test_warm_started_uct_solves_the_detour(seed: int) -> None:
    mdp = detour()
    rng = np.random.default_rng(seed)
    concrete = concretize(mdp.as_mdp(), state("s0"), [plan("a", "b", "c")], rng)
    result = warm_started_uct(mdp.as_mdp(), state("s0"), concrete.plans, rng)
    assert result.goal_plan is not None
    assert replay(mdp, "s0", result.goal_plan).goal_reached


def test_a_goal_found_in_warm_up_is_returned_without_simulations() -> None:
    mdp = warm_chain()
    rng = np.random.default_rng(0)
    concrete = concretize(mdp.as_mdp(), state("s0"), [plan("w"), plan("a", "b")], rng)
    result = warm_started_uct(mdp.as_mdp(), state("s0"), concrete.plans, rng)
    # the rollout from [a, b]'s leaf s2 reaches the goal
    assert result.goal_plan == (drawn("a", 0), drawn("b", 0), drawn("c", 0))
    assert (result.counters.warm_start_plans, result.counters.simulations) == (2, 0)
    assert result.best_outcome is not None and result.best_outcome.state == state("s1")


def test_a_goal_found_by_a_rollout_ends_the_search() -> None:
    mdp = warm_chain()
    result = warm_started_uct(mdp.as_mdp(), state("s0"), (), np.random.default_rng(1))
    assert result.goal_plan is not None
    assert replay(mdp, "s0", result.goal_plan).goal_reached


def test_root_at_the_goal() -> None:
    mdp = warm_chain()
    result = warm_started_uct(mdp.as_mdp(), state("s3"), (), np.random.default_rng(0))
    assert (result.goal_plan, result.best_action, result.stop_reason) == ((), None, "goal")


def test_budget_and_best_action_without_a_goal() -> None:
    mdp = graph(
        [
            ("s0", "a", det("s1", 3.0)),
            ("s0", "w", det(None)),
            ("s1", "b", (Option(0, "s0", 0.0), Option(1, None))),
        ]
    )
    settings = SearchSettings(budget=25)
    result = warm_started_uct(
        mdp.as_mdp(), state("s0"), (), np.random.default_rng(0), settings=settings
    )
    assert result.goal_plan is None and result.stop_reason == "budget"
    assert result.counters.simulations == 25
    assert result.best_action == drawn("a", 0)
    assert result.best_outcome is not None and result.best_outcome.reward == 3.0
    assert result.tree_stats.root_visits >= 25
    # every ψ draw and T call the search made was counted, rollouts included
    assert result.counters.samples == mdp.calls["sample"]
    assert result.counters.transitions == mdp.calls["step"] + mdp.calls["infeasible"]


def test_duplicate_draws_are_dropped_and_states_merge() -> None:
    mdp = loop()
    settings = SearchSettings(budget=30)
    tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
    result = warm_started_uct(
        mdp.as_mdp(),
        state("s0"),
        (),
        np.random.default_rng(0),
        settings=settings,
        policies=zero_value(settings),
        tree=tree,
    )
    assert result.counters.simulations == 30
    assert len(tree) == 2  # s0 and s1, however often they are reached
    assert tree.num_kappas(state("s0"), move("a")) == 1
    assert tree.num_kappas(state("s1"), move("b")) == 1
    assert mdp.calls["step"] == 2  # T paid once per κ child
    assert mdp.calls["sample"] > 2  # later identical draws were dropped


def test_simulations_stop_at_the_horizon_from_the_episode_start() -> None:
    mdp = loop()
    settings = SearchSettings(horizon=20)
    policies = zero_value(settings)
    tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
    rng = np.random.default_rng(0)
    ends = []
    for _ in range(10):
        sim = simulate(
            tree, mdp.as_mdp(), rng, depth0=17, gamma=0.99, horizon=20, policies=policies
        )
        assert len(sim.path) <= 3
        ends.append(sim.end)
    assert ends[:2] == ["leaf", "horizon"]
    assert set(ends[1:]) == {"horizon"}
    # the horizon path s0 -a-> s1 -b-> s0 -a-> s1: G = 1 + 0.99 + 0.99² = 2.9701
    assert sim.returns == pytest.approx((2.9701, 1.99, 1.0))
    with pytest.raises(ValueError, match="no steps left"):
        warm_started_uct(mdp.as_mdp(), state("s0"), (), rng, settings=settings, depth0=20)


def test_deadline_is_honoured_between_simulations() -> None:
    mdp = detour()
    rng = np.random.default_rng(0)
    concrete = concretize(mdp.as_mdp(), state("s0"), [plan("a", "b", "c")], rng)
    result = warm_started_uct(
        mdp.as_mdp(), state("s0"), concrete.plans, rng, deadline=time.monotonic() - 1.0
    )
    assert result.stop_reason == "deadline"
    assert (result.counters.warm_start_plans, result.counters.simulations) == (0, 0)
    assert result.goal_plan is None and result.best_action is None


def run(seed: int) -> tuple[object, ...]:
    mdp = detour()
    rng = np.random.default_rng(seed)
    concrete = concretize(mdp.as_mdp(), state("s0"), [plan("a", "b", "c"), plan("u")], rng)
    tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
    result = warm_started_uct(
        mdp.as_mdp(), state("s0"), concrete.plans, rng, settings=SearchSettings(), tree=tree
    )
    return concrete, result, tree.snapshot(repr), dict(mdp.calls)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_same_seed_same_search(seed: int) -> None:
    assert run(seed) == run(seed)


def test_plain_uct_is_deterministic_too() -> None:
    def once() -> tuple[object, ...]:
        mdp = graph(
            [
                ("s0", "a", tuple(Option(i, f"t{i}", float(i)) for i in range(4))),
                ("s0", "b", (Option(0, "s0"), Option(1, None))),
                ("t0", "a", det("s0")),
                ("t1", "a", det("t2", 1.0)),
                ("t2", "a", det("t3")),
                ("t3", "a", det("t0")),
            ]
        )
        tree = SearchTree.for_root(mdp.as_mdp(), state("s0"))
        result = warm_started_uct(
            mdp.as_mdp(), state("s0"), (), np.random.default_rng(11), tree=tree
        )
        return result, tree.snapshot(repr)

    first = once()
    assert first == once()
