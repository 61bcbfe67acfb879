"""Test doubles for planners that talk to a language model: scripted reply texts, recorded asks.

:class:`ScriptedReplyBackendDouble` stands in for an :class:`~stalm.llm.backends.base.LLMBackend`:
each request is answered with texts a test chose (a fixed queue, or a function of the request),
and every request is kept so a test can read the prompts the planner sent.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from stalm.domain.actions import DiscreteAction
from stalm.llm.backends.base import LLMReply, LLMRequest, LLMResponse

Responder = Callable[[LLMRequest], Sequence[str]]


def plan_reply(plan: Sequence[DiscreteAction]) -> str:
    """A reply in the paper's template whose plan is ``plan``."""
    steps = ", ".join("(" + ", ".join(repr(x) for x in a.as_tuple()) + ")" for a in plan)
    return (
        "## Possible Challenges for unachieved goals based on current state ##\n"
        "1. scripted by a test double\n"
        f"## Plan for unachieved goals ##\nplan = [{steps}]"
    )


class ScriptedReplyBackendDouble:
    """A backend double: scripted reply texts per request; records every request it gets.

    With a ``responder`` each request's texts come from calling it; with a ``queue`` request
    ``k`` gets ``queue[k]`` (the last entry repeats). A request for ``n`` replies gets the
    texts cycled to ``n``.
    """

    def __init__(
        self,
        *,
        responder: Responder | None = None,
        queue: Sequence[Sequence[str]] | None = None,
        name: str = "scripted-double",
        model: str = "scripted",
    ) -> None:
        if (responder is None) == (queue is None):
            raise ValueError("give exactly one of responder and queue")
        self._responder = responder
        self._queue = [list(texts) for texts in queue] if queue is not None else []
        self._name = name
        self._model = model
        self.requests: list[LLMRequest] = []

    @property
    def name(self) -> str:
        return self._name

    @property
    def model(self) -> str:
        return self._model

    @property
    def description(self) -> str:
        return "a test double answering with scripted reply texts"

    def complete(self, request: LLMRequest) -> LLMResponse:
        index = len(self.requests)
        self.requests.append(request)
        if self._responder is not None:
            texts = list(self._responder(request))
        else:
            texts = self._queue[min(index, len(self._queue) - 1)]
        if not texts:
            raise AssertionError("the scripted double has no reply text for this request")
        replies = tuple(
            LLMReply(
                text=texts[i % len(texts)],
                prompt_tokens=len(request.user.split()) if i == 0 else 0,
                completion_tokens=len(texts[i % len(texts)].split()),
                latency_s=0.0,
                finish_reason="stop",
            )
            for i in range(request.n)
        )
        return LLMResponse(replies=replies, backend=self._name, model=self._model)
