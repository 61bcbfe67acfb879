"""Re-execute a saved plan in a fresh scene and check that it reaches the goal.

Every action's motions are swept again in the state it is applied to
(:func:`stalm.domain.verify.check_action`); a plan whose motions collide, or which does not end
in a goal state, is reported as failed with the step and the reason.

A result file is not trusted (:func:`replay_result_json`): the plan starts from the problem's
own initial state (never the state stored in the file), the file's problem hash must match
the problem's (an old file without one gets a warning), every number must be finite, and each
step is checked as it is executed: its parameters must fit the state it is applied to and the
state it produces must be sound (:func:`~stalm.domain.verify.check_consistency`,
:func:`~stalm.domain.verify.check_outcome`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from stalm.domain.mdp import Domain
from stalm.domain.params import Action
from stalm.domain.serialize import action_from_json
from stalm.domain.verify import check_action, check_consistency, check_outcome
from stalm.errors import StalmError
from stalm.world.problem import PROBLEM_HASH_FIELD, Problem
from stalm.world.state import State


@dataclass(frozen=True)
class ReplayReport:
    reached_goal: bool
    steps_executed: int
    failed_step: int | None
    reason: str | None
    states: tuple[State, ...]
    actions: tuple[Action, ...]
    warnings: tuple[str, ...] = ()
    """What could not be confirmed but did not stop the replay (e.g. an old file's missing
    problem hash)."""


def replay_plan(problem: Problem, start: State, actions: list[Action]) -> ReplayReport:
    """Execute ``actions`` from ``start`` in a fresh simulator, checking every step: its
    precondition, that its parameters fit the state, its motions, and the state it makes."""
    domain = Domain.create(problem)
    spec = problem.spec
    try:
        state = start
        states = [state]
        for index, action in enumerate(actions):
            why = domain.precondition_failure(state, action.discrete)
            if why is None:
                failure = check_consistency(
                    domain.sim, spec, state, action, domain.samplers.handle_target
                )
                failure = failure or check_action(domain.sim, state, action)
                if failure is None:
                    after = domain.next_state(state, action)
                    failure = check_outcome(domain.sim, spec, after, action)
                why = None if failure is None else str(failure)
            if why is not None:
                return ReplayReport(False, index, index, why, tuple(states), tuple(actions))
            state = after
            states.append(state)
        reached = domain.is_goal(state)
        reason = None if reached else "the plan ends before the goal"
        return ReplayReport(reached, len(actions), None, reason, tuple(states), tuple(actions))
    finally:
        domain.close()


def replay_result_json(problem: Problem, data: dict[str, Any]) -> ReplayReport:
    """Replay the plan of a ``stalm solve --json`` file (or an experiment record), trusting
    nothing in it but the plan (see the module docstring)."""
    if not isinstance(data, dict):
        raise StalmError("not a stalm result file: not a JSON object")
    if data.get("termination") == "error":
        raise StalmError(f"the result records an error, not a plan: {str(data.get('error'))[:200]}")
    warnings: list[str] = []
    recorded = data.get(PROBLEM_HASH_FIELD)
    if recorded is None:
        warnings.append(
            f"the result has no problem hash (an older stalm wrote it): cannot confirm it was "
            f"planned for this {problem.name}"
        )
    elif recorded != problem.content_hash:
        raise StalmError(
            f"the result was planned for another problem than {problem.source} (problem hash "
            f"{str(recorded)[:40]} in the file, {problem.content_hash} here); give the problem "
            "file it was made with (--problem FILE)"
        )
    stored = data.get("initial_state")
    if stored is not None and not _is_state(stored, problem.initial_state):
        warnings.append(
            "the file's initial_state is not the problem's; the plan is replayed from the "
            "problem's initial state"
        )
    plan = data.get("plan")
    if not isinstance(plan, list):
        raise StalmError("not a stalm result file: no 'plan' list")
    actions = []
    for index, item in enumerate(plan):
        try:
            actions.append(action_from_json(item))
        except StalmError as error:
            raise StalmError(f"step {index + 1} of the plan: {error}") from None
    report = replay_plan(problem, problem.initial_state, actions)
    return dataclasses.replace(report, warnings=tuple(warnings))


def _is_state(data: object, state: State) -> bool:
    """Does ``data`` (a stored State) equal ``state``? Anything unreadable does not."""
    try:
        return State.from_json(data) == state  # type: ignore[arg-type]
    except Exception:  # a malformed stored state is simply not the problem's
        return False
