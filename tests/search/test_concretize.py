"""Concretize (Algorithm 2) and the failure kinds of the paper's Figure 5."""

from __future__ import annotations

import numpy as np
import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.outcome import Infeasibility
from stalm.search.concretize import TaskPlan, concretize
from tests.search.synthetic import drawn, move, plan, state, warm_chain


def test_the_four_failure_kinds() -> None:
    mdp = warm_chain()
    plans = [
        plan("b"),  # b's precondition is false at s0
        plan("w"),  # w is legal at s0 but ψ never finds a κ
        plan("a", "b"),  # feasible, but s2 is not the goal
        TaskPlan.unreadable("no plan list (plan = [...]) in the reply"),
        plan("a", "x"),  # fails at its second step
    ]
    result = concretize(mdp.as_mdp(), state("s0"), plans, np.random.default_rng(0))
    assert not result.success
    assert result.solution is None
    assert result.failures == (
        (0, "precondition_violation"),
        (1, "lack_of_3d_understanding"),
        (2, "partially_achieved_goal"),
        (3, "unparseable"),
        (4, "lack_of_3d_understanding"),
    )
    first, _, partial, unreadable, second_step = result.plans
    assert first.failed_step == 0
    assert first.detail is not None and "b is not applicable in s0" in first.detail
    assert isinstance(first.steps[0].kappa, Infeasibility)
    assert first.steps[0].kappa.kind == "precondition"
    assert first.steps[0].outcome.reward == -6.0
    assert partial.actions == (drawn("a", 0), drawn("b", 0))
    assert [step.outcome.state for step in partial.steps] == [state("s1"), state("s2")]
    assert unreadable.steps == ()
    assert unreadable.detail == "no plan list (plan = [...]) in the reply"
    assert second_step.failed_step == 1
    assert second_step.actions == (drawn("a", 0),)
    # precondition violations are not sampled: ψ ran for w, a, b, a, x only
    assert mdp.calls["sample"] == 5
    assert result.counts.samples == 5
    assert result.counts.transitions == mdp.calls["step"] + mdp.calls["infeasible"] == 6


def test_success_stops_everything() -> None:
    mdp = warm_chain()
    plans = [plan("w"), plan("a", "b", "c", "a"), plan("a")]
    result = concretize(mdp.as_mdp(), state("s0"), plans, np.random.default_rng(0))
    assert result.success
    assert result.solution == (drawn("a", 0), drawn("b", 0), drawn("c", 0))
    assert len(result.plans) == 2  # the third plan was never tried
    assert result.plans[1].reached_goal and result.plans[1].failure is None
    assert len(result.plans[1].steps) == 3  # the step after the goal was not tried
    assert result.failures == ((0, "lack_of_3d_understanding"),)


@pytest.mark.parametrize(("depth0", "horizon"), [(0, 2), (5, 7)])
def test_the_horizon_cuts_a_plan(depth0: int, horizon: int) -> None:
    result = concretize(
        warm_chain().as_mdp(),
        state("s0"),
        [plan("a", "b", "c")],
        np.random.default_rng(0),
        depth0=depth0,
        horizon=horizon,
    )
    (cut,) = result.plans
    assert not result.success
    assert cut.failure == "partially_achieved_goal"
    assert cut.truncated
    assert len(cut.steps) == 2


def test_an_empty_plan_is_unparseable() -> None:
    result = concretize(
        warm_chain().as_mdp(), state("s0"), [TaskPlan(())], np.random.default_rng(0)
    )
    assert result.failures == ((0, "unparseable"),)


def test_unparseable_plans_carry_no_actions() -> None:
    with pytest.raises(ValueError, match="unparseable"):
        TaskPlan((move("a"),), "garbled")


def test_a_plan_a_planner_did_not_find_is_no_plan_not_an_unreadable_reply() -> None:
    reason = "the predicate abstraction of this state has no plan to the goal"
    result = concretize(
        warm_chain().as_mdp(),
        state("s0"),
        [TaskPlan.none_found(reason), TaskPlan.unreadable("garbled")],
        np.random.default_rng(0),
    )
    assert result.failures == ((0, "no_plan"), (1, "unparseable"))
    assert result.plans[0].detail == reason and result.plans[1].detail == "garbled"
    with pytest.raises(ValueError, match="no_plan"):
        TaskPlan((move("a"),), no_plan=reason)
    with pytest.raises(ValueError, match="no_plan"):
        TaskPlan((), "garbled", no_plan=reason)


P5_GRILL_LAST = (
    Open("kitchen_door"),
    Pick("sprite"),
    Place("sprite", "on", "counter1"),
    Pick("beef_grill"),
    Place("beef_grill", "on", "counter3"),
    Pick("coke"),
    Place("coke", "on", "counter1"),
    Pick("beef_grill"),
    Place("beef_grill", "on", "counter1"),
)


def test_backtracking_draws_again_the_placement_of_a_can_that_blocks_the_grill(
    domain_factory,
) -> None:
    """P5 with the grill last: one draw per step often leaves a can at the front of counter1,
    where the grill finds no room (the plan fails at its last step, blocked by the can);
    drawing the cans' placements again solves some of those, over the same seeds."""
    domain = domain_factory("P5")
    root = domain.problem.initial_state
    blocked, rescued = 0, 0
    for seed in range(6):
        plain = concretize(
            domain, root, [TaskPlan(P5_GRILL_LAST)], np.random.default_rng(seed), kappa_tries=3
        )
        failed = plain.plans[0]
        if plain.success or failed.failed_step != 8:
            continue
        if not {"coke", "sprite"} & set(failed.steps[-1].kappa.blockers):  # type: ignore[union-attr]
            continue
        blocked += 1
        redone = concretize(
            domain,
            root,
            [TaskPlan(P5_GRILL_LAST)],
            np.random.default_rng(seed),
            kappa_tries=3,
            backtracks=6,
        )
        assert redone.counts.samples > plain.counts.samples
        if redone.success:
            rescued += 1
            assert [step.action for step in redone.plans[0].steps] == list(P5_GRILL_LAST)
    assert blocked >= 2, "the cans block the grill in several seeds"
    assert rescued >= 1, f"backtracking rescued none of {blocked} blocked plans"
