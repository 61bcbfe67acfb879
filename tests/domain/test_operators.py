"""The operators against real collision queries: occlusion, placement, doors, determinism."""

from __future__ import annotations

import numpy as np

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.domain.params import PickParams
from stalm.world.relations import at_position


def _opened(domain: Domain, rng: np.random.Generator):
    _action, outcome = domain.sample_and_step(
        domain.problem.initial_state, Open("kitchen_door"), rng
    )
    assert outcome.feasible, outcome.failure
    return outcome.state


def test_picking_a_blocked_object_fails_and_names_its_blockers(domain_factory, rng) -> None:
    domain = domain_factory("P2")
    state = _opened(domain, rng)
    _, outcome = domain.sample_and_step(state, Pick("salter"), rng)
    assert not outcome.feasible
    assert outcome.failure is not None and outcome.failure.kind == "arm_collision"
    assert {"bottle2", "bottle3"} <= set(outcome.failure.blockers)
    assert outcome.reward == -6.0 and outcome.state == state
    action, outcome = domain.sample_and_step(state, Pick("bottle2"), rng)
    assert outcome.feasible and isinstance(action.params, PickParams)
    assert outcome.state.held is not None and outcome.state.held.obj == "bottle2"
    assert not outcome.state.has_pose("bottle2")


def test_closed_door_blocks_travel_and_open_unblocks_it(domain_factory, rng) -> None:
    domain = domain_factory("P2")
    state = domain.problem.initial_state
    _, outcome = domain.sample_and_step(state, Pick("bottle2"), rng)
    assert not outcome.feasible and outcome.failure is not None
    assert outcome.failure.kind == "base_path_blocked"
    assert outcome.failure.blockers == ("kitchen_door",)
    opened = _opened(domain, rng)
    assert opened.is_open("kitchen_door")
    _, outcome = domain.sample_and_step(opened, Pick("bottle2"), rng)
    assert outcome.feasible
    _, again = domain.sample_and_step(opened, Open("kitchen_door"), rng)
    assert not again.feasible and again.failure is not None and again.failure.kind == "precondition"


def test_placed_objects_satisfy_their_at_position(domain_factory, rng) -> None:
    domain = domain_factory("P2")
    spec = domain.problem.spec
    state = _opened(domain, rng)
    state = domain.sample_and_step(state, Pick("bottle2"), rng)[1].state
    _, placed = domain.sample_and_step(state, Place("bottle2", "on", "counter1"), rng)
    assert placed.feasible, placed.failure
    assert at_position(spec, placed.state, "bottle2", "on", "counter1")
    state = domain.sample_and_step(placed.state, Pick("bottle3"), rng)[1].state
    _, beside = domain.sample_and_step(state, Place("bottle3", "left_of", "bottle2"), rng)
    assert beside.feasible, beside.failure
    assert at_position(spec, beside.state, "bottle3", "left_of", "bottle2")
    assert at_position(spec, beside.state, "bottle3", "on", "counter1")
    assert not at_position(spec, beside.state, "bottle3", "right_of", "bottle2")


def test_p5_grill_placed_first_leaves_no_room_for_the_cans(domain_factory) -> None:
    domain = domain_factory("P5")
    rng = np.random.default_rng(11)
    state = _opened(domain, rng)
    for action in (Pick("beef_grill"), Place("beef_grill", "on", "counter1"), Pick("coke")):
        for _ in range(5):
            _, outcome = domain.sample_and_step(state, action, rng)
            if outcome.feasible:
                break
        assert outcome.feasible, (action, outcome.failure)
        state = outcome.state
    for _ in range(3):
        _, outcome = domain.sample_and_step(state, Place("coke", "on", "counter1"), rng)
        assert not outcome.feasible
        assert outcome.failure is not None and "beef_grill" in outcome.failure.blockers


def test_the_same_seed_gives_the_same_samples(problems) -> None:
    results = []
    for _ in range(2):
        domain = Domain.create(problems["P2"])
        rng = np.random.default_rng(123)
        state = domain.problem.initial_state
        trace = []
        for action in (Open("kitchen_door"), Pick("bottle2"), Place("bottle2", "on", "counter1")):
            for _ in range(4):
                drawn, outcome = domain.sample_and_step(state, action, rng)
                trace.append((drawn, outcome.failure))
                if outcome.feasible:
                    break
            state = outcome.state
        results.append((trace, state))
        domain.close()
    assert results[0] == results[1]
    assert at_position(problems["P2"].spec, results[0][1], "bottle2", "on", "counter1")


def test_rewards_goal_and_a_full_p2_plan(domain_factory) -> None:
    domain = domain_factory("P2")
    rng = np.random.default_rng(5)
    state = domain.problem.initial_state
    plan = [
        Open("kitchen_door"),
        Pick("bottle2"),
        Place("bottle2", "on", "counter1"),
        Pick("bottle3"),
        Place("bottle3", "on", "counter1"),
        Pick("salter"),
        Place("salter", "right_of", "bottle1"),
    ]
    rewards, state = _rewards_along(domain, state, plan, rng, tries=5)
    assert domain.is_goal(state)
    # the last PLACE makes both goal atoms true (+3 each) and reaches the goal (+100)
    assert rewards[-1] == 3.0 * 2 + 100.0
    assert sum(rewards[:-1]) == 0.0


def test_legal_actions_follow_the_symbolic_preconditions(domain_factory, rng) -> None:
    domain = domain_factory("P2")
    state = domain.problem.initial_state
    legal = domain.legal_actions(state)
    assert set(legal) == {Pick(o) for o in ("salter", "bottle1", "bottle2", "bottle3")} | {
        Open("kitchen_door")
    }
    holding = domain.sample_and_step(_opened(domain, rng), Pick("bottle2"), rng)[1].state
    legal = domain.legal_actions(holding)
    # n(R) regions + 4 directions x 3 other objects
    assert len(legal) == 7 + 4 * 3
    assert all(isinstance(a, Place) and a.obj == "bottle2" for a in legal)
    assert domain.precondition_failure(holding, Pick("salter")) is not None
    assert "not a region" in str(
        domain.precondition_failure(holding, Place("bottle2", "on", "salter"))
    )


def test_picking_a_goal_object_off_its_goal_and_placing_it_back_nets_zero(domain_factory) -> None:
    """P6's grill starts on its goal counter: −3 for picking it off, +3 for putting it back."""
    domain = domain_factory("P6")
    rng = np.random.default_rng(3)
    state = domain.problem.initial_state
    assert at_position(domain.problem.spec, state, "beef_grill", "on", "counter2")
    plan = [Open("kitchen_door"), Pick("beef_grill"), Place("beef_grill", "on", "counter2")]
    rewards, _ = _rewards_along(domain, state, plan, rng, tries=10)
    assert rewards == [0.0, -3.0, 3.0]
    assert sum(rewards) == 0.0


def _rewards_along(domain, state, plan, rng, tries: int):
    """Each action's reward along ``plan`` (up to ``tries`` κ draws a step), and the end state."""
    rewards = []
    for action in plan:
        for _ in range(tries):
            _, outcome = domain.sample_and_step(state, action, rng)
            if outcome.feasible:
                break
        assert outcome.feasible, (action, outcome.failure)
        rewards.append(outcome.reward)
        state = outcome.state
    return rewards, state
