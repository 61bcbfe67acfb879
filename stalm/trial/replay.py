"""Re-execute a saved plan in a fresh scene and check that it reaches the goal, every step
checked as the planner checked it (:func:`replay_plan`); a plan a step of which fails, or which
does not end in a goal state, is reported as failed with the step and the reason.

A result file is not trusted (:func:`replay_result_json`): the plan starts from the problem's
own initial state (never the state stored in the file), the file's problem hash must match
the problem's (an old file without one gets a warning), and the plan is read by
:func:`read_plan`, the one reading of a record's plan that ``stalm replay``, ``view`` and
``rerun`` share: every number finite, every one the robot can have in the problem's world and
every motion of a size a replay can sweep (:mod:`stalm.domain.plan_bounds`), all before
anything is densified.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from stalm.domain.mdp import Domain
from stalm.domain.params import Action
from stalm.domain.plan_bounds import out_of_bounds
from stalm.domain.serialize import action_from_json
from stalm.domain.verify import check_action, check_consistency, check_outcome
from stalm.errors import StalmError
from stalm.json_object import JsonObject
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
    precondition, that its numbers are bounded (actions not read by :func:`read_plan` are
    checked here), that its parameters fit the state (its base path and arm motion start where
    the robot is), that its motions are collision-free and that the state it makes is sound
    (:func:`~stalm.domain.verify.check_consistency`, :func:`~stalm.domain.verify.check_action`,
    :func:`~stalm.domain.verify.check_outcome`)."""
    domain = Domain.create(problem)
    spec = problem.spec
    try:
        state = start
        states = [state]
        for index, action in enumerate(actions):
            why = domain.precondition_failure(state, action.discrete)
            why = why or out_of_bounds(spec, problem.robot, action)
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


def replay_result_json(problem: Problem, data: JsonObject) -> ReplayReport:
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
    actions = read_plan(problem, data.get("plan"))
    report = replay_plan(problem, problem.initial_state, actions)
    return dataclasses.replace(report, warnings=tuple(warnings))


def read_plan(problem: Problem, plan: object) -> list[Action]:
    """The executed plan of a result record for ``problem``, each step parsed
    (:func:`~stalm.domain.serialize.action_from_json`) and its numbers bounded by the problem's
    world and the robot (:func:`~stalm.domain.plan_bounds.out_of_bounds`) before anything is
    built from it; a StalmError names the first step that is not, and why."""
    if not isinstance(plan, list):
        raise StalmError("not a stalm result file: no 'plan' list")
    actions = []
    for index, item in enumerate(plan):
        try:
            action = action_from_json(item, 1 + len(problem.robot.arm_joints))
        except StalmError as error:
            raise StalmError(f"step {index + 1} of the plan: {error}") from None
        why = out_of_bounds(problem.spec, problem.robot, action)
        if why is not None:
            raise StalmError(f"step {index + 1} of the plan: {why}")
        actions.append(action)
    return actions


def _is_state(data: object, state: State) -> bool:
    """Does ``data`` (a stored State) equal ``state``? Anything unreadable does not."""
    try:
        return State.from_json(data) == state  # type: ignore[arg-type]
    except Exception:  # a malformed stored state is simply not the problem's
        return False
