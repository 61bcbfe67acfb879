"""Each problem's ``optimal_length`` is the length of a minimal plan worked out by hand, and
that plan is a real one: ψ grounds every step and the goal holds at its end (P1-P3)."""

from __future__ import annotations

import numpy as np
import pytest

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.search.hcount import occluder_set
from stalm.trial.replay import replay_plan


def move(obj: str, region: str) -> tuple[DiscreteAction, DiscreteAction]:
    return Pick(obj), Place(obj, "on", region)


OPEN = Open("kitchen_door")
MINIMAL_PLANS: dict[str, tuple[DiscreteAction, ...]] = {
    # the door (everything in the kitchen is behind it), then each of the six objects once
    "P1": (
        OPEN,
        *move("bottle3", "table1"),
        *move("bottle1", "table1"),
        *move("salter3", "table2"),
        *move("salter2", "shelf_lower"),
        *move("salter1", "counter2"),
        *move("bottle2", "counter2"),
    ),
    # the door, the two bottles in front of the salter, the salter
    "P2": (
        OPEN,
        *move("bottle2", "counter1"),
        *move("bottle3", "counter1"),
        Pick("salter"),
        Place("salter", "right_of", "bottle1"),
    ),
    # the door, the four bottles in front of milk and coke (front row first), milk and coke
    "P3": (
        OPEN,
        *move("cocoa", "counter2"),
        *move("whiskey", "counter2"),
        *move("water", "counter2"),
        *move("wine", "counter2"),
        *move("milk", "counter2"),
        *move("coke", "counter2"),
    ),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(MINIMAL_PLANS))
def test_optimal_length_is_a_real_minimal_plan(domain_factory, initial_literals, name: str) -> None:
    domain = domain_factory(name)
    problem = domain.problem
    plan = MINIMAL_PLANS[name]
    assert problem.spec.optimal_length == len(plan)
    # a lower bound from the initial predicates: every goal object and every movable object
    # that occludes one (Hcount's M) is moved at least once (pick + place), every door in M
    # is opened; the plan meets it, so no shorter plan exists
    state = problem.initial_state
    occluders = occluder_set(problem, initial_literals(name), state)
    doors = {door.name for door in problem.spec.doors}
    goal_objects = {g.obj for g in problem.goal}
    must_move = (occluders - doors) | goal_objects
    assert len(plan) == 2 * len(must_move) + len(occluders & doors)
    # and it is feasible: ψ grounds each step (a few draws each), the goal holds, replay agrees
    rng = np.random.default_rng(0)
    executed = []
    for action in plan:
        for _ in range(10):
            kappa, outcome = domain.sample_and_step(state, action, rng)
            if outcome.feasible:
                break
        assert outcome.feasible, f"{action}: {outcome.failure}"
        executed.append(kappa)
        state = outcome.state
    assert domain.is_goal(state)
    assert replay_plan(problem, problem.initial_state, executed).reached_goal
