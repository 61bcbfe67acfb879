"""Did a change alter what the planners do? Two results logs, trial by trial.

A change meant to keep behaviour (a refactor, a faster engine) is checked by running the same
experiment before and after it and comparing what each seed did: the same termination (goal,
horizon, timeout, ..., or an error with the same message, process ids and temporary folders
aside), the same actions, and continuous values within a tolerance
(:data:`~stalm.geometry.tolerance.CONTINUOUS_TOLERANCE`: another machine rounds the last bits
of IK and trigonometry differently). Times are not compared; a trial that timed out executed
as far as the clock let it, so two runs may differ there without a change.

Trials are paired by row (arm), problem and trial number, after a retried trial's newest
record has replaced the older ones. A pair whose seeds, problem files or budgets differ (where
both records say) ran something else: "not comparable", not a changed plan. A log that holds
one trial twice under different settings (a row run with and without ``--set``) cannot be
paired and is refused.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal, get_args

from stalm.errors import StalmError
from stalm.experiments.report import latest_records
from stalm.geometry.tolerance import CONTINUOUS_TOLERANCE, first_difference

Verdict = Literal["same", "different", "not comparable", "only before", "only after"]
VERDICTS: tuple[Verdict, ...] = get_args(Verdict)
TrialId = tuple[str, str, int]
"""Arm, problem, trial number."""
SAME_RUN = ("seed", "problem_sha", "problem_hash", "time_budget_s")
"""What a pair must share to have run the same thing (compared where both records have it)."""
RUN_SPECIFIC = re.compile(r"\b(pid) \d+|(stalm-[a-z]+-)\d+-\w+")
"""What names one run in an error message: a process id, a temporary folder of stalm's."""


@dataclass(frozen=True)
class TrialComparison:
    """One trial of the two logs: the verdict and, unless the same, why."""

    arm: str
    problem: str
    trial: int
    verdict: Verdict
    why: str = ""


@dataclass(frozen=True)
class PlanComparison:
    """Every trial of either log, in (arm, problem, trial) order."""

    trials: tuple[TrialComparison, ...]

    def counts(self) -> dict[tuple[str, str], dict[Verdict, int]]:
        """Per (arm, problem): how many trials got each verdict."""
        table: dict[tuple[str, str], dict[Verdict, int]] = {}
        for trial in self.trials:
            row = table.setdefault((trial.arm, trial.problem), {})
            row[trial.verdict] = row.get(trial.verdict, 0) + 1
        return table

    @property
    def all_same(self) -> bool:
        """Every trial of both logs has its pair, and every pair did the same."""
        return all(trial.verdict == "same" for trial in self.trials)


def compare_plans(
    before: Iterable[dict[str, Any]],
    after: Iterable[dict[str, Any]],
    tolerance: float = CONTINUOUS_TOLERANCE,
    names: tuple[str, str] = ("before", "after"),
) -> PlanComparison:
    """Pair the trials of ``before`` and ``after`` (records of results logs, named ``names``
    in errors) and compare what each pair did. A record without a whole-number trial or a
    list as its plan, or a trial held twice under different keys, is a StalmError."""
    old, new = _by_trial(before, names[0]), _by_trial(after, names[1])
    trials = []
    for key in sorted(old.keys() | new.keys()):
        arm, problem, number = key
        if key not in new:
            trials.append(TrialComparison(arm, problem, number, "only before"))
        elif key not in old:
            trials.append(TrialComparison(arm, problem, number, "only after"))
        else:
            verdict, why = _compare(old[key], new[key], tolerance)
            trials.append(TrialComparison(arm, problem, number, verdict, why))
    return PlanComparison(tuple(trials))


def _by_trial(records: Iterable[dict[str, Any]], name: str) -> dict[TrialId, Mapping[str, Any]]:
    found: dict[TrialId, Mapping[str, Any]] = {}
    for record in latest_records(records):  # a retried trial's newest record
        arm, problem = record.get("arm") or record.get("planner"), record.get("problem")
        number, plan = record.get("trial", 0), record.get("plan")
        plan = [] if plan is None else plan
        if isinstance(number, bool) or not isinstance(number, int) or not isinstance(plan, list):
            raise StalmError(
                f"{name}: the record of {arm} on {problem} needs a whole-number trial and a "
                f"list as its plan, got trial {number!r} and a plan of type {type(plan).__name__}"
            )
        key = (str(arm), str(problem), number)
        if key in found:
            raise StalmError(
                f"{name}: {arm} ran trial {number} of {problem} twice with different settings "
                "(trial keys): compare the logs of one configuration each"
            )
        found[key] = record
    return found


def _compare(
    old: Mapping[str, Any], new: Mapping[str, Any], tolerance: float
) -> tuple[Verdict, str]:
    for field in SAME_RUN:
        if field in old and field in new and old[field] != new[field]:
            return "not comparable", f"{field} {old[field]!r} vs {new[field]!r}"
    ended = old.get("termination"), new.get("termination")
    if ended[0] != ended[1]:
        return "different", f"ended {ended[0]} vs {ended[1]}"
    if ended[0] == "error" and _run_free(old.get("error")) != _run_free(new.get("error")):
        return "different", f"error {old.get('error')!r} vs {new.get('error')!r}"
    if bool(old.get("success")) != bool(new.get("success")):
        return "different", f"success {bool(old.get('success'))} vs {bool(new.get('success'))}"
    before_plan, after_plan = list(old.get("plan") or []), list(new.get("plan") or [])
    for index, (a, b) in enumerate(zip(before_plan, after_plan, strict=False)):
        difference = first_difference(a, b, tolerance)
        if difference is not None:
            return "different", f"action {index + 1} ({_name(a)}): {difference}"
    if len(before_plan) != len(after_plan):
        return "different", f"{len(before_plan)} actions vs {len(after_plan)}"
    return "same", ""


def _run_free(message: object) -> str:
    """An error message with what names its run (:data:`RUN_SPECIFIC`) left out."""
    return RUN_SPECIFIC.sub(lambda found: (found.group(1) or found.group(2)) + " #", str(message))


def _name(step: Any) -> str:
    """An executed action's discrete part as ``pick(bottle2)``."""
    action = step.get("action") if isinstance(step, Mapping) else None
    if not isinstance(action, list) or not action:
        return "?"
    return f"{action[0]}({', '.join(map(str, action[1:]))})"
