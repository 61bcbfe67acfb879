"""What every planner returns, and the one interface every planner implements.

A :class:`PlanResult` is plain data: whether the goal was reached, the executed plan with every
continuous parameter, wall time split by phase, counters, and the failure taxonomy of the
task plans a proposer offered. ``to_json`` is what ``stalm solve --json`` writes and
``stalm replay`` reads.
"""

from __future__ import annotations

import math
import numbers
import os
from dataclasses import asdict, dataclass, field
from typing import Protocol

from stalm.domain.params import Action
from stalm.domain.serialize import action_to_json
from stalm.errors import StalmError
from stalm.json_object import JsonObject
from stalm.trial.details import RunDetails
from stalm.world.problem import Problem
from stalm.world.state import State


@dataclass(frozen=True)
class PhaseTimes:
    """Wall-clock seconds by phase (they add up to at most ``total``), and the CPU seconds
    the trial used (``cpu``: this process and the Fast Downward runs it waited for). Wall time
    depends on what else the machine runs; CPU time much less, so a run made while the cores
    were shared can still be compared with a quiet one."""

    predicates: float = 0.0
    proposer: float = 0.0
    """The task-plan proposer's queries: a language model's calls, or Fast Downward's runs."""
    concretize: float = 0.0
    tree_search: float = 0.0
    execution: float = 0.0
    total: float = 0.0
    cpu: float = 0.0
    setup: float = 0.0
    """Building the trial's scene, domain and method before its first decision (on a scene of
    thousands of objects, seconds of the budget)."""

    def phases(self) -> dict[str, float]:
        """The seconds of each phase (not ``total`` or ``cpu``), in the order printed."""
        names = ("setup", "predicates", "proposer", "concretize", "tree_search", "execution")
        return {name: getattr(self, name) for name in names}


def phase_times_json(data: object) -> dict[str, float]:
    """A record's ``times`` (read through :mod:`stalm.trial.records`), its finite numbers
    only; {} for anything that is not a mapping (a record is untrusted input)."""
    if not isinstance(data, dict):
        return {}
    return {
        str(key): float(value)
        for key, value in data.items()
        if isinstance(value, numbers.Real)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    }


def cpu_seconds() -> float:
    """User and system CPU seconds of this process and of its children that have ended."""
    times = os.times()
    return times.user + times.system + times.children_user + times.children_system


@dataclass(frozen=True)
class Counters:
    llm_calls: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    transitions: int = 0
    samples: int = 0
    collision_checks: int = 0
    simulations: int = 0
    replans: int = 0


@dataclass(frozen=True)
class PlanResult:
    """The outcome of one planning run."""

    problem: str
    planner: str
    seed: int
    success: bool
    plan: tuple[Action, ...]
    states: tuple[State, ...]
    times: PhaseTimes
    counters: Counters
    termination: str
    """'goal', 'timeout', 'horizon' or 'no_progress' ('replay_failed' when the plan did not
    replay; ``stalm solve`` names 'unreachable_goal' when its check found the goal
    unreachable and the run did not reach it)."""
    llm_plan_failures: dict[str, int] = field(default_factory=dict)
    details: RunDetails = field(default_factory=RunDetails)

    def to_json(self) -> JsonObject:
        return {
            "problem": self.problem,
            "planner": self.planner,
            "seed": self.seed,
            "success": self.success,
            "termination": self.termination,
            "plan_length": len(self.plan),
            "plan": [action_to_json(a) for a in self.plan],
            "initial_state": self.states[0].to_json() if self.states else None,
            "final_state": self.states[-1].to_json() if self.states else None,
            "times": asdict(self.times),
            "counters": asdict(self.counters),
            "llm_plan_failures": dict(self.llm_plan_failures),
            "details": self.details.to_json(),
        }


def check_seed(seed: object, name: str = "seed") -> int:
    """``seed`` if it is an integer >= 0, else a StalmError naming ``name``. The CLI
    (``--seed``) and every planner's :meth:`Planner.solve` (``seed``) check with this one
    function, so the Python API refuses what the command refuses, in the same words (a
    negative seed failed deep inside numpy)."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or int(seed) < 0:
        raise StalmError(f"{name} must be a non-negative integer, got {seed!r}")
    return int(seed)


def check_time_budget(budget: object, name: str = "time_budget_s") -> float | None:
    """``budget`` if it is None (the problem's) or a finite number of seconds above 0, else a
    StalmError naming ``name`` (NaN disabled the deadline: every comparison with it is
    false)."""
    if budget is None:
        return None
    if isinstance(budget, numbers.Real) and not isinstance(budget, bool):
        seconds = float(budget)
        if math.isfinite(seconds) and seconds > 0:
            return seconds
    raise StalmError(f"{name} must be a positive number of seconds, got {budget!r}")


class Planner(Protocol):
    """A G-TAMP planner: STaLM or a baseline."""

    @property
    def name(self) -> str: ...

    def solve(self, problem: Problem, seed: int, time_budget_s: float | None = None) -> PlanResult:
        """Plan (and execute in simulation) until the goal, the horizon or the time budget."""
        ...
