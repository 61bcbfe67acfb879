"""Does an executed plan respect the grill trap of P5 and P6 (paper §4.4, Figure 6)?

The trap is a claim of the problems (their descriptions and docs/problems.md): with the grill
on its goal counter, nothing else can be put there; the grill goes last. This checks it where
a user meets it, on replayed solves: each record's plan is re-executed from the problem's
initial state (:func:`~stalm.trial.replay.replay_result_json`, which trusts nothing else in
the record) and every step that puts an object on the grill's goal counter while the grill
stands on it is named. ``benchmarks/grill_trap.py`` runs it over experiment records.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

from stalm.domain.actions import Place
from stalm.experiments.results_log import read_records
from stalm.trial.replay import replay_result_json
from stalm.world.problem import PROBLEM_HASH_FIELD, Problem
from stalm.world.relations import at_position
from stalm.world.state import State


@dataclass(frozen=True)
class TrapCheck:
    """One replayed record: did it reach the goal, and which steps broke the trap."""

    problem: str
    seed: int | None
    reached_goal: bool
    grill_last: bool
    violations: tuple[str, ...]


def trap_counters(problem: Problem) -> dict[str, str]:
    """Each grill of the problem and the region its goal puts it on."""
    grills = {obj.name for obj in problem.spec.objects if obj.shape == "grill"}
    return {g.obj: g.ref for g in problem.goal if g.obj in grills and g.direction == "on"}


def trap_violations(problem: Problem, states: tuple[State, ...]) -> tuple[str, ...]:
    """Each step of an executed plan (its states in order) that puts an object on a grill's
    goal counter while that grill stands on it."""
    spec = problem.spec
    found = []
    for grill, counter in trap_counters(problem).items():
        for step, (before, after) in enumerate(itertools.pairwise(states), start=1):
            placed = before.held.obj if before.held is not None else None
            if placed is None or placed == grill or after.held is not None:
                continue
            if at_position(spec, after, placed, "on", counter) and at_position(
                spec, after, grill, "on", counter
            ):
                found.append(f"step {step}: {placed} placed on {counter} with {grill} on it")
    return tuple(found)


def check_record(problem: Problem, record: dict[str, object]) -> TrapCheck:
    """Replay a result record of ``problem`` and check its plan against the trap."""
    report = replay_result_json(problem, record)
    last = report.actions[-1].discrete if report.actions else None
    counters = trap_counters(problem)
    # the last action puts a grill down on its goal counter ('on' it, or beside a can there)
    grill_last = (
        isinstance(last, Place)
        and last.obj in counters
        and at_position(problem.spec, report.states[-1], last.obj, "on", counters[last.obj])
    )
    seed = record.get("seed")
    return TrapCheck(
        problem.name,
        seed if isinstance(seed, int) else None,
        report.reached_goal,
        grill_last,
        trap_violations(problem, report.states),
    )


@dataclass(frozen=True)
class FirstProposal:
    """The trap's fidelity in one trial (paper §4.4, Figure 5's "lack of 3D understanding"):
    of the task plans in the first proposal, how many put a grill on its goal counter before
    another object goes there, and how many of those Concretize found infeasible."""

    plans: int
    grill_first: int
    grill_first_failed: int


def first_proposal(problem: Problem, record: dict[str, object]) -> FirstProposal | None:
    """The first proposal's task plans of a record's step log (None when it logged none, or
    logged it in another shape). A plan counts as infeasible when Concretize stopped it at a
    step (``failed_step``), not when it merely ran short of the goal."""
    details = record.get("details")
    log = details.get("step_log") if isinstance(details, dict) else None
    step = log[0] if isinstance(log, list) and log else None
    proposals = step.get("proposals") if isinstance(step, dict) else None
    proposal = proposals[0] if isinstance(proposals, list) and proposals else None
    plans = proposal.get("plans") if isinstance(proposal, dict) else None
    if not isinstance(plans, list):
        return None
    plans = [plan for plan in plans if isinstance(plan, dict) and plan.get("actions")]
    counters = trap_counters(problem)
    first = [plan for plan in plans if _grill_first(plan["actions"], counters)]
    failed = [plan for plan in first if plan.get("failed_step") is not None]
    return FirstProposal(len(plans), len(first), len(failed))


def _grill_first(actions: list[list[str]], counters: dict[str, str]) -> bool:
    """Does a task plan (actions as lists of words) put a grill on its goal counter and then
    another object on that counter?"""
    for grill, counter in counters.items():
        grill_at = [i for i, a in enumerate(actions) if a == ["place", grill, "on", counter]]
        if grill_at and any(
            a[:1] == ["place"] and a[1] != grill and a[2:] == ["on", counter]
            for a in actions[grill_at[0] + 1 :]
        ):
            return True
    return False


def check_results(path: Path, problems: dict[str, Problem]) -> list[TrapCheck]:
    """Every solved record of ``path`` (an experiment's JSON lines; a retried trial's last
    record) whose problem is in ``problems`` as it is now: a record solved on another version
    of the problem (P5 and P6 before the trap bound: another problem hash) is left out."""
    checks = []
    for record in read_records(path).latest_by_key().values():
        problem = problems.get(str(record.get("problem")))
        if problem is not None and record.get("success") and same_version(problem, record):
            checks.append(check_record(problem, record))
    return checks


def same_version(problem: Problem, record: dict[str, object]) -> bool:
    """Whether ``record`` was solved on ``problem`` as it is now (a record too old to carry
    its problem's hash is taken at its word)."""
    recorded = record.get(PROBLEM_HASH_FIELD)
    return recorded is None or recorded == problem.content_hash
