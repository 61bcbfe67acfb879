"""What a tree planner (STaLM, STaLM w/o UCT, UCT, UCT-with-Hcount) records of its run.

:class:`TreeDetails` is the method's part of a result's details: which proposer it asked and
how often, the settings that decide how it searched and executed, the root visits a kept tree
brought into each step, and the step log (:mod:`stalm.trial.step_log`); the noisy proposer
adds what it injected, Hcount how its leaves' predicates were made.
"""

from __future__ import annotations

from dataclasses import dataclass

from stalm.json_object import JsonObject, record_json
from stalm.proposers.noisy import NoiseRecord
from stalm.settings.tree import ExecutionRule
from stalm.trial.step_log import StepRecord


@dataclass(frozen=True)
class TreeSettingsRecord:
    """The settings a tree planner's record keeps (``details.settings``): each is explained
    where the run's settings tree declares it."""

    reuse_tree: bool
    feedback: bool
    execution: ExecutionRule
    kappa_tries: int
    backtracks: int
    goal_atom_lost: float


@dataclass(frozen=True)
class HcountLeaves:
    """How Hcount's leaves got their predicates: computed from scratch, or brought forward
    from the parent's with the cached update."""

    predicates_from_scratch: int
    predicates_brought_forward: int


@dataclass(frozen=True)
class TreeDetails:
    """A tree planner's record (``proposer`` None and ``proposals`` 0 for UCT)."""

    proposer: str | None
    settings: TreeSettingsRecord
    proposals: int
    feedback_steps_learned: int
    reused_root_visits: tuple[int, ...]
    """Per real step whose tree was kept: the visits its root already had."""
    step_log: tuple[StepRecord, ...]
    noise: NoiseRecord | None = None
    hcount_leaves: HcountLeaves | None = None

    def to_json(self) -> JsonObject:
        return record_json(self, omitted_when_none={"noise", "hcount_leaves"})
