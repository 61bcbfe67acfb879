"""A generated problem's proof of solvability: its task plan grounded in the simulator.

:func:`ground_witness` executes the construction's task plan step by step with the operators'
own samplers ψ (the same draws a planner makes, from a seeded generator, up to
:data:`DRAWS_PER_STEP` per step). Where a step is blocked by a movable object the construction
did not plan to move (a clutter object beside a chain, an occluder put where it hides the next
goal), the blockers are moved out of the way first, onto the regions the construction keeps
for that, and the plan is grounded again from the start (at most :data:`REPAIRS` times); a
placement that finds no room is tried on the next such region. The grounded plan is then
replayed in a fresh scene (:func:`stalm.trial.replay.replay_plan`, the check ``stalm
replay`` makes): a problem is written only with a witness that replays to its goal.

This is construction, not planning: no search over orders or alternatives beyond these local
repairs, so a problem no planner here could solve is not made easier by it, and a problem it
cannot ground is simply not generated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stalm.domain.actions import DiscreteAction, Pick, Place
from stalm.domain.mdp import Domain
from stalm.domain.params import Action
from stalm.trial.replay import replay_plan
from stalm.world.problem import Problem
from stalm.world.state import State

DRAWS_PER_STEP = 3
"""ψ draws per step before the step counts as failed (each draw makes the operator's tries)."""
REPAIRS = 10
"""Times the plan is amended (blockers moved first, another region for a placement)."""


@dataclass(frozen=True)
class Witness:
    """A grounded plan that reaches the goal, with the states it passes through."""

    plan: tuple[DiscreteAction, ...]
    actions: tuple[Action, ...]
    states: tuple[State, ...]


@dataclass(frozen=True)
class NoWitness:
    """Why the plan could not be grounded: the step and the sampler's last failure."""

    reason: str


def ground_witness(
    problem: Problem,
    plan: tuple[DiscreteAction, ...],
    dumps: tuple[str, ...],
    rng: np.random.Generator,
) -> Witness | NoWitness:
    """Ground ``plan`` (amended as the module docstring says) and replay it; ``dumps`` are the
    regions an object in the way may be put on."""
    domain = Domain.create(problem)
    movable = {obj.name for obj in problem.spec.objects}
    try:
        for _ in range(REPAIRS + 1):
            grounded = _ground(domain, problem, plan, rng)
            if isinstance(grounded, Witness):
                return _replayed(problem, grounded)
            index, failure_blockers, reason = grounded
            amended = _amend(plan, index, failure_blockers & movable, dumps)
            if amended is None:
                return NoWitness(reason)
            plan = amended
        return NoWitness(f"still failing after {REPAIRS} amendments: {reason}")
    finally:
        domain.close()


def _ground(
    domain: Domain, problem: Problem, plan: tuple[DiscreteAction, ...], rng: np.random.Generator
) -> Witness | tuple[int, set[str], str]:
    """The grounded plan, or (failing step, its blockers, why)."""
    state = problem.initial_state
    actions: list[Action] = []
    states = [state]
    for index, step in enumerate(plan):
        why = domain.precondition_failure(state, step)
        if why is not None:
            return index, set(), f"step {index + 1} {step}: {why}"
        last = None
        for _ in range(DRAWS_PER_STEP):
            action, outcome = domain.sample_and_step(state, step, rng)
            if action is not None and outcome.feasible:
                actions.append(action)
                state = outcome.state
                states.append(state)
                break
            last = outcome.failure
        else:
            blockers = set(last.blockers) if last is not None else set()
            return index, blockers, f"step {index + 1} {step}: {last}"
    if not domain.is_goal(state):
        return len(plan), set(), "the plan ends short of the goal"
    return Witness(plan, tuple(actions), tuple(states))


def _amend(
    plan: tuple[DiscreteAction, ...], index: int, blockers: set[str], dumps: tuple[str, ...]
) -> tuple[DiscreteAction, ...] | None:
    """The plan with the failing step's movable blockers moved first (before the pick that
    starts the failing step's move; a blocker the plan moves later is then picked again from
    where it was put), or its placement on the next region; None if neither applies."""
    if index >= len(plan):
        return None
    step = plan[index]
    if isinstance(step, Place) and step.direction == "on" and step.ref in dumps and not blockers:
        later = dumps[(dumps.index(step.ref) + 1) % len(dumps)]
        if later == step.ref:
            return None
        return (*plan[:index], Place(step.obj, "on", later), *plan[index + 1 :])
    if isinstance(step, Place):
        blockers = blockers - {step.obj}
    if not blockers:
        return None
    start = index - 1 if isinstance(step, Place) else index  # before the pick of that move
    moves: list[DiscreteAction] = []
    for count, obj in enumerate(sorted(blockers)):
        moves += [Pick(obj), Place(obj, "on", dumps[count % len(dumps)])]
    return (*plan[:start], *moves, *plan[start:])


def _replayed(problem: Problem, witness: Witness) -> Witness | NoWitness:
    report = replay_plan(problem, problem.initial_state, list(witness.actions))
    if not report.reached_goal:
        return NoWitness(f"the grounded plan does not replay: {report.reason}")
    return witness
