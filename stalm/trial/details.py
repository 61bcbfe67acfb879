"""What a result records about its run beyond the plan, typed: :attr:`PlanResult.details`.

Every online trial records the same things around its method's own record: whether the
executed plan replayed to the goal in a fresh scene, and every language-model query with what
it cost (:class:`RunDetails`). The method's own record is its planner's to type
(:class:`MethodDetails`: STaLM's step log, SayCan's decisions, PDDLStream's iterations), so a
reader in Python gets fields, not string keys. ``to_json`` writes the published shape
(``result_schema.json``): the method's fields first, then ``replay_failure``, then the
queries, then why a goal the problem check found unreachable was not reached.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from stalm.json_object import JsonObject, record_json


class MethodDetails(Protocol):
    """A planner's own record of its run (its fields are its own)."""

    @property
    def proposer(self) -> str | None:
        """The task-plan proposer the method asked (None: it asks none, or a bare model)."""
        ...

    def to_json(self) -> JsonObject:
        """The record's fields as JSON, in the order the result file shows them."""
        ...


class DirectRecord:
    """Base of the record of a method that asks no task-plan proposer (EP-SayCan and
    Iterative-Replanning prompt their model themselves, PDDLStream plans with Fast Downward):
    a frozen dataclass whose JSON is its fields."""

    @property
    def proposer(self) -> None:
        return None

    def to_json(self) -> JsonObject:
        return record_json(self)


@dataclass(frozen=True)
class QueryRecord:
    """One language-model query of a trial, for the result: was it answered from the reply
    cache, how long it took now, and how long the calls that made its replies took."""

    from_cache: bool
    seconds: float
    original_seconds: float
    plans: int
    truncated_plans: int

    def to_json(self) -> JsonObject:
        """The fields in order, the seconds rounded to the microsecond."""
        seconds = {"seconds": self.seconds, "original_seconds": self.original_seconds}
        return record_json(self) | {key: round(value, 6) for key, value in seconds.items()}


@dataclass(frozen=True)
class ReplayCheck:
    """The executed plan's replay in a fresh scene: why it failed (None: it did not fail, or
    the run did not reach the goal, so nothing was replayed)."""

    failure: str | None = None


@dataclass(frozen=True)
class UnreachableGoal:
    """A run that did not reach a goal the problem check had found unreachable: why the goal
    cannot be reached, and how the run itself ended ('timeout', 'horizon', ...)."""

    why: str
    run_ended_by: str


@dataclass(frozen=True)
class RunDetails:
    """A result's details: the method's record, the replay check, the model queries."""

    method: MethodDetails | None = None
    replay: ReplayCheck | None = None
    """None: the result records no replay check (a generated problem's witness)."""
    queries: tuple[QueryRecord, ...] = ()
    unreachable_goal: UnreachableGoal | None = None

    @property
    def proposer(self) -> str | None:
        """The task-plan proposer the method asked, if any."""
        return None if self.method is None else self.method.proposer

    def to_json(self) -> JsonObject:
        data = {} if self.method is None else self.method.to_json()
        if self.replay is not None:
            data["replay_failure"] = self.replay.failure
        if self.queries:
            data["llm_queries"] = [query.to_json() for query in self.queries]
            data["llm_queries_from_cache"] = sum(query.from_cache for query in self.queries)
            data["llm_seconds_now"] = round(sum(query.seconds for query in self.queries), 6)
            data["truncated_plans"] = sum(query.truncated_plans for query in self.queries)
        if self.unreachable_goal is not None:
            data["unreachable_goal"] = self.unreachable_goal.why
            data["run_ended_by"] = self.unreachable_goal.run_ended_by
        return data
