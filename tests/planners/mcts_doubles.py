"""Test doubles for the LLM-MCTS tests (tests only): backends with scripted replies, and a cheap
stand-in for the predicate engine.

They implement :class:`~stalm.llm.backends.base.LLMBackend` and record every request, so tests
can count the model calls the prior makes and check the seeds it sends.
"""

from __future__ import annotations

from collections.abc import Sequence

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.llm.backends.base import LLMReply, LLMRequest, LLMResponse
from stalm.predicates.literals import GroundLiteral
from stalm.world.state import State


def plan_text(plan: Sequence[DiscreteAction]) -> str:
    """A reply in the prompt's template: ``plan = [('pick', 'x'), ...]``."""
    steps = ", ".join(repr(action.as_tuple()) for action in plan)
    return f"## Plan ##\nplan = [{steps}]"


class _RecordingBackendDouble:
    """Shared plumbing: name, model, the recorded requests, replies built by ``texts_for``."""

    name = "double"
    model = "scripted"
    description = "a scripted test double"

    def __init__(self) -> None:
        self.requests: list[LLMRequest] = []

    def texts_for(self, request: LLMRequest) -> list[str]:
        raise NotImplementedError

    def complete(self, request: LLMRequest) -> LLMResponse:
        self.requests.append(request)
        texts = self.texts_for(request)
        replies = tuple(
            LLMReply(texts[i % len(texts)], 100 if i == 0 else 0, 20, 0.0, "stop")
            for i in range(request.n)
        )
        return LLMResponse(replies, self.name, self.model)


class ScriptedRepliesBackendDouble(_RecordingBackendDouble):
    """Answers every request with the same reply texts (cycled to the batch size)."""

    def __init__(self, texts: Sequence[str]) -> None:
        super().__init__()
        self.texts = list(texts)

    def texts_for(self, request: LLMRequest) -> list[str]:
        return self.texts


class PlanFollowingBackendDouble(_RecordingBackendDouble):
    """Answers as a model that knows one correct task plan and reads the prompt's state.

    From the literals in the prompt's ``:init`` it finds the plan step that comes next — place
    the held object; else open a closed door; else pick the first object whose placement in the
    plan does not hold yet — and replies with the plan from that step on, in every sample.
    """

    def __init__(self, plan: Sequence[DiscreteAction]) -> None:
        super().__init__()
        self.plan = tuple(plan)

    def next_step(self, init: str) -> int:
        def holds(name: str, *args: str) -> bool:
            return repr(GroundLiteral(name, args).as_tuple()) in init

        for index, action in enumerate(self.plan):
            if isinstance(action, Place) and holds("RobotHolding", action.obj):
                return index
        for index, action in enumerate(self.plan):
            if isinstance(action, Open) and holds("IsClosed", action.door):
                return index
        for index, action in enumerate(self.plan):
            if isinstance(action, Pick):
                place = next(
                    (a for a in self.plan[index:] if isinstance(a, Place) and a.obj == action.obj),
                    None,
                )
                if place is None or not holds("AtPosition", place.obj, place.direction, place.ref):
                    return index
        return 0

    def texts_for(self, request: LLMRequest) -> list[str]:
        init = request.user.split("(:goal")[0]
        return [plan_text(self.plan[self.next_step(init) :])]


class SymbolicLiteralsDouble:
    """A cheap stand-in for ``PredicateEngine.compute(state).literals``: only the hand's literal
    and the closed doors (no geometry), and a record of the states it was asked about."""

    def __init__(self, doors: Sequence[str] = ()) -> None:
        self.doors = tuple(doors)
        self.states: list[State] = []

    def __call__(self, state: State) -> tuple[GroundLiteral, ...]:
        self.states.append(state)
        hand = (
            GroundLiteral("HandAvailable")
            if state.held is None
            else GroundLiteral("RobotHolding", (state.held.obj,))
        )
        closed = tuple(GroundLiteral("IsClosed", (d,)) for d in self.doors if not state.is_open(d))
        return (hand, *closed)
