"""The one interface every language-model backend implements.

Planners ask for a batch of task plans with an :class:`LLMRequest` and get an
:class:`LLMResponse` back, whatever runs the model: a hosted API, a local server or the small
model embedded in the package. Keeping requests and replies as plain frozen values lets the
reply cache key them, lets tests compare them, and lets results record exactly what was asked.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from stalm.errors import StalmError
from stalm.llm.constraints import OutputConstraint

__all__ = ["LLMBackend", "LLMReply", "LLMRequest", "LLMResponse", "OutputConstraint"]


@dataclass(frozen=True)
class LLMRequest:
    """One batch query: the prompt, how many samples, and how to sample them.

    ``seed`` makes sampling repeatable where the backend allows: sample ``i`` of the batch uses
    ``seed + i``, so asking for more samples later extends a batch instead of redrawing it.
    """

    system: str
    user: str
    n: int = 1
    temperature: float = 1.0
    max_tokens: int = 1024
    seed: int | None = None
    constraint: OutputConstraint | None = None
    deadline: float | None = None
    """A ``time.monotonic()`` value: past it a backend starts no new sample and cuts a running
    one (``finish_reason`` 'deadline'), so a trial's time budget bounds its model calls too.
    It decides when to stop, not what is drawn, so it is not part of the cache key."""

    def __post_init__(self) -> None:
        # Batch size, temperature and token budget come from settings the CLI lets users
        # override, so a bad value is a user error with the field named.
        if self.n < 1:
            raise StalmError(f"LLM request field 'n' must be at least 1, got {self.n}")
        if self.max_tokens < 1:
            raise StalmError(
                f"LLM request field 'max_tokens' must be at least 1, got {self.max_tokens}"
            )
        if self.temperature < 0:
            raise StalmError(
                f"LLM request field 'temperature' must be non-negative, got {self.temperature}"
            )

    def sample_seed(self, index: int) -> int | None:
        """The seed of sample ``index`` (None when the request is unseeded)."""
        return None if self.seed is None else self.seed + index


@dataclass(frozen=True)
class LLMReply:
    """One sampled reply with what it cost.

    Token counts add up over a response to what the server reported: a prompt shared by
    several samples of one server call is counted on the first of them only.
    ``finish_reason`` is the server's (``"stop"``, ``"length"``, ...) when it gave one; a
    ``"length"`` reply was cut by ``max_tokens`` and will usually fail to parse; a
    ``"deadline"`` reply was cut by the request's deadline and is never cached.
    """

    text: str
    prompt_tokens: int
    completion_tokens: int
    latency_s: float
    finish_reason: str | None = None


@dataclass(frozen=True)
class LLMResponse:
    """The replies to one :class:`LLMRequest`, in sample-index order.

    ``from_cache`` is true when every reply came from the reply cache (no model was run).
    ``cached_replies`` counts the replies that came from the cache and ``cached_seconds`` is
    what producing them took when they were made (the cache stores each reply's share of its
    call's wall time), so a caller can count a replayed call at its original cost.
    """

    replies: tuple[LLMReply, ...]
    backend: str
    model: str
    from_cache: bool = False
    cached_replies: int = 0
    cached_seconds: float = 0.0

    @property
    def texts(self) -> tuple[str, ...]:
        return tuple(reply.text for reply in self.replies)

    @property
    def prompt_tokens(self) -> int:
        return sum(reply.prompt_tokens for reply in self.replies)

    @property
    def completion_tokens(self) -> int:
        return sum(reply.completion_tokens for reply in self.replies)


@runtime_checkable
class LLMBackend(Protocol):
    """Anything that turns an :class:`LLMRequest` into an :class:`LLMResponse`.

    ``name`` identifies the kind of backend (``"embedded"``, ``"openai-compatible"``) and
    ``model`` the model it runs; together they scope the reply cache. ``description`` is one
    or two sentences for people (the CLI prints it), e.g. what a tiny model is good for.
    Failures a user can cause (unreachable server, wrong key, unknown model, prompt too long)
    raise :class:`~stalm.errors.StalmError` naming the server and model.
    """

    @property
    def name(self) -> str: ...

    @property
    def model(self) -> str: ...

    @property
    def description(self) -> str: ...

    def complete(self, request: LLMRequest) -> LLMResponse: ...
