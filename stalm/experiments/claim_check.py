"""Do executed plans meet what a problem says about its own geometry?

A problem's description states facts a solve must meet: "the salter stands behind two bottles;
clear them" (P2), "milk and coke ... are boxed in by the rows in front" (P3), "the closed door
is in the way of every cross-room move" (P1). Such a claim is only true if no solve gets
round it, as the grill trap once was not (the arm reached over the grill in every solve). So
the claims are checked on replayed solves, as a user meets them, not in one sampler call:

- **occluders**: each object that occludes picking another in the initial state (the paper's
  PickOccludedBy, computed by motion planning) has moved, and each door that does is open,
  when that other object is first picked;
- **doors**: no object is put down in another room than the one it was picked in while every
  door is closed.

The grill trap has its own check (:mod:`stalm.experiments.trap_check`).
``benchmarks/problem_claims.py`` runs these over experiment records.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from stalm.domain.actions import DiscreteAction, Pick
from stalm.errors import StalmError
from stalm.experiments.results_log import read_records
from stalm.predicates.literals import GroundLiteral
from stalm.trial.replay import ReplayReport, replay_result_json
from stalm.world.problem import Problem
from stalm.world.problem_record import record_problem
from stalm.world.relations import region_of
from stalm.world.state import State

MOVED_M = 0.01
"""How far (metres, in the plane) an occluder must be from where it stood to count as moved:
above the state's quantum and any settling, below any placement the samplers make."""


@dataclass(frozen=True)
class ClaimCheck:
    """One replayed record: did it reach the goal, and which steps broke a claim."""

    problem: str
    seed: int | None
    reached_goal: bool
    occluders: Mapping[str, frozenset[str]]
    picks_checked: int
    """First picks of an object that had occluders at the start: what the occluder claim
    was checked on (0 says the check saw nothing, not that the plan is sound)."""
    violations: tuple[str, ...]


def pick_occluders(literals: Iterable[GroundLiteral]) -> dict[str, frozenset[str]]:
    """Each object and the objects (or closed doors) that occlude picking it, from a state's
    literals (``PickOccludedBy(o, x)``); objects nothing occludes are left out."""
    found: dict[str, set[str]] = {}
    for literal in literals:
        if literal.name == "PickOccludedBy":
            found.setdefault(literal.args[0], set()).add(literal.args[1])
    return {obj: frozenset(xs) for obj, xs in sorted(found.items())}


def occluder_violations(
    occluders: Mapping[str, frozenset[str]],
    doors: frozenset[str],
    states: tuple[State, ...],
    actions: tuple[DiscreteAction, ...],
) -> tuple[str, ...]:
    """Each first PICK of an object made while one of its initial occluders still stands
    where it stood, or is a door (of ``doors``) still closed (``states[0]`` is the initial
    state; ``states[k]`` the one ``actions[k]`` is applied to)."""
    start = states[0]
    found = []
    for step, (before, action) in _first_picks(states, actions):
        for occluder in sorted(occluders.get(action.obj, ())):
            if occluder in doors:
                if not before.is_open(occluder):
                    found.append(f"step {step}: {action.obj} picked with {occluder} closed")
            elif _unmoved(start, before, occluder):
                found.append(f"step {step}: {action.obj} picked with {occluder} still in the way")
    return tuple(found)


def _first_picks(
    states: tuple[State, ...], actions: tuple[DiscreteAction, ...]
) -> list[tuple[int, tuple[State, Pick]]]:
    """(step, (state before, action)) of each object's first PICK, steps counted from 1."""
    picked: set[str] = set()
    found = []
    for step, (before, action) in enumerate(zip(states, actions, strict=False), start=1):
        if isinstance(action, Pick) and action.obj not in picked:
            picked.add(action.obj)
            found.append((step, (before, action)))
    return found


def door_violations(problem: Problem, states: tuple[State, ...]) -> tuple[str, ...]:
    """Each PLACE that puts an object down in another room than the one it was picked in
    while every door is closed (each region names its room)."""
    spec = problem.spec
    if not spec.doors:
        return ()
    found = []
    picked_in: dict[str, str] = {}
    for step, (before, after) in enumerate(itertools.pairwise(states), start=1):
        if before.held is None and after.held is not None:
            source = region_of(spec, before, after.held.obj)
            if source is not None:
                picked_in[after.held.obj] = spec.region(source).room
        elif before.held is not None and after.held is None:
            obj = before.held.obj
            target = region_of(spec, after, obj)
            if target is None or obj not in picked_in:
                continue
            room = spec.region(target).room
            if room != picked_in[obj] and not after.open_doors:
                found.append(
                    f"step {step}: {obj} carried from the {picked_in[obj]} to the {room} "
                    "with every door closed"
                )
    return tuple(found)


def check_replay(
    problem: Problem,
    occluders: Mapping[str, frozenset[str]],
    report: ReplayReport,
    seed: int | None = None,
) -> ClaimCheck:
    """Every claim against one replayed plan."""
    doors = frozenset(door.name for door in problem.spec.doors)
    actions = tuple(action.discrete for action in report.actions)
    violations = occluder_violations(occluders, doors, report.states, actions)
    violations += door_violations(problem, report.states)
    checked = sum(
        1 for _, (_, pick) in _first_picks(report.states, actions) if occluders.get(pick.obj)
    )
    return ClaimCheck(problem.name, seed, report.reached_goal, occluders, checked, violations)


def initial_occluders(problem: Problem) -> dict[str, frozenset[str]]:
    """:func:`pick_occluders` of the problem's initial state, its predicates computed with the
    default settings (the paper's: every object's occlusions)."""
    from stalm.motion.base_motion import BasePlanner
    from stalm.predicates.engine import PredicateEngine
    from stalm.predicates.samples import PredicateSettings
    from stalm.world.scene import Sim

    with Sim(problem.spec) as sim:
        engine = PredicateEngine(problem, sim, BasePlanner(sim), PredicateSettings())
        literals = engine.compute(problem.initial_state).literals
    return pick_occluders(literals)


@dataclass(frozen=True)
class CheckedResults:
    """The checks of one results file's solved records, and the solved records left out
    (each with why: solved on another version of its problem, or a plan that is refused)."""

    checks: tuple[ClaimCheck, ...]
    skipped: tuple[str, ...]


def check_results(path: Path) -> CheckedResults:
    """Every solved record of ``path`` (an experiment's JSON lines; a retried trial's last
    record), replayed on the problem it was solved on (the one it carries, or for an older
    record the one it names, if that is still the same problem); the others are named in
    ``skipped``, not checked."""
    checks = []
    skipped = []
    occluders: dict[str, dict[str, frozenset[str]]] = {}
    for record in read_records(path).latest_by_key().values():
        if not record.get("success"):
            continue
        where = f"{record.get('problem')} seed {record.get('seed')}"
        try:
            problem = record_problem(record, str(path))
        except StalmError as error:  # P5/P6 before the trap bound: another problem hash
            skipped.append(f"{where}: {error}")
            continue
        if problem.content_hash not in occluders:
            occluders[problem.content_hash] = initial_occluders(problem)
        seed = record.get("seed")
        try:
            report = replay_result_json(problem, record)
        except StalmError as error:
            skipped.append(f"{where}: {error}")
            continue
        checks.append(
            check_replay(
                problem,
                occluders[problem.content_hash],
                report,
                seed if isinstance(seed, int) else None,
            )
        )
    return CheckedResults(tuple(checks), tuple(skipped))


def _unmoved(start: State, now: State, obj: str) -> bool:
    """Does ``obj`` rest in ``now`` where it rested in ``start``?"""
    if not now.has_pose(obj) or not start.has_pose(obj):
        return False
    a, b = start.pose(obj), now.pose(obj)
    return math.hypot(a.x - b.x, a.y - b.y) < MOVED_M
