"""Did a change alter what the planners do? Two results logs, trial by trial.

A change meant to keep behaviour (a refactor, a faster engine) is checked by running the same
experiment before and after it and comparing the plans each seed executed: the same success,
the same actions, continuous values within a tolerance
(:data:`~stalm.geometry.tolerance.CONTINUOUS_TOLERANCE`: another machine rounds the last bits
of IK and trigonometry differently). Times are not compared. Trials are paired by arm, problem
and trial number; a pair whose seeds or problem hashes differ ran something else and is
reported as such, not as a changed plan.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

from stalm.geometry.tolerance import CONTINUOUS_TOLERANCE, first_difference

Verdict = Literal["same", "different", "not comparable", "only before", "only after"]
TrialId = tuple[str, str, int]
"""Arm, problem, trial number."""


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
        """Every trial of both logs has its pair, and every pair executed the same plan."""
        return all(trial.verdict == "same" for trial in self.trials)


def compare_plans(
    before: Iterable[Mapping[str, Any]],
    after: Iterable[Mapping[str, Any]],
    tolerance: float = CONTINUOUS_TOLERANCE,
) -> PlanComparison:
    """Pair the trials of ``before`` and ``after`` (records of results logs; a retried trial's
    last record counts) and compare what each pair executed."""
    old, new = _by_trial(before), _by_trial(after)
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


def _by_trial(records: Iterable[Mapping[str, Any]]) -> dict[TrialId, Mapping[str, Any]]:
    found: dict[TrialId, Mapping[str, Any]] = {}
    for record in records:
        arm = str(record.get("arm") or record.get("planner"))
        found[(arm, str(record.get("problem")), int(record.get("trial") or 0))] = record
    return found


def _compare(
    old: Mapping[str, Any], new: Mapping[str, Any], tolerance: float
) -> tuple[Verdict, str]:
    for field in ("seed", "problem_hash"):
        if old.get(field) != new.get(field):
            return "not comparable", f"{field} {old.get(field)!r} vs {new.get(field)!r}"
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


def _name(step: Any) -> str:
    """An executed action's discrete part as ``pick(bottle2)``."""
    action = step.get("action") if isinstance(step, Mapping) else None
    if not isinstance(action, list) or not action:
        return "?"
    return f"{action[0]}({', '.join(map(str, action[1:]))})"
