"""Re-execute a saved plan in a fresh scene and check that it reaches the goal.

Every action's motions are swept again in the state it is applied to
(:func:`stalm.domain.verify.check_action`); a plan whose motions collide, or which does not end
in a goal state, is reported as failed with the step and the reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from stalm.domain.mdp import Domain
from stalm.domain.params import Action
from stalm.domain.serialize import action_from_json
from stalm.domain.verify import check_action
from stalm.errors import StalmError
from stalm.world.problem import Problem
from stalm.world.state import State


@dataclass(frozen=True)
class ReplayReport:
    reached_goal: bool
    steps_executed: int
    failed_step: int | None
    reason: str | None
    states: tuple[State, ...]
    actions: tuple[Action, ...]


def replay_plan(problem: Problem, start: State, actions: list[Action]) -> ReplayReport:
    """Execute ``actions`` from ``start`` in a fresh simulator, checking every motion."""
    domain = Domain.create(problem)
    try:
        state = start
        states = [state]
        for index, action in enumerate(actions):
            why = domain.precondition_failure(state, action.discrete)
            if why is None:
                failure = check_action(domain.sim, state, action)
                why = None if failure is None else str(failure)
            if why is not None:
                return ReplayReport(False, index, index, why, tuple(states), tuple(actions))
            state = domain.next_state(state, action)
            states.append(state)
        reached = domain.is_goal(state)
        reason = None if reached else "the plan ends before the goal"
        return ReplayReport(reached, len(actions), None, reason, tuple(states), tuple(actions))
    finally:
        domain.close()


def replay_result_json(problem: Problem, data: dict[str, Any]) -> ReplayReport:
    """Replay the plan of a ``stalm solve --json`` file."""
    try:
        start = (
            State.from_json(data["initial_state"])
            if data.get("initial_state")
            else problem.initial_state
        )
        actions = [action_from_json(item) for item in data["plan"]]
    except (KeyError, TypeError, AssertionError) as error:
        raise StalmError(f"not a stalm result file: {error!r}") from None
    return replay_plan(problem, start, actions)
