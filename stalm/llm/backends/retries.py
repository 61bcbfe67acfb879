"""How long and how often one call to a language-model server is tried.

A request's ``deadline`` (a trial's time budget) bounds a call as a whole, not just each read
(:func:`run_until`); rate limits, server errors and timeouts are retried with bounded
exponential backoff (:class:`RetryPolicy`). Kept apart from the chat API client
(:mod:`stalm.llm.backends.openai_compatible`) because this is the part that must hold against
any server, however slowly or badly it answers.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar, cast

from stalm.errors import StalmError

if TYPE_CHECKING:  # imported where used: it adds a third of a second to every CLI start
    import openai

RETRYABLE_STATUS = frozenset({408, 409, 429})
"""HTTP statuses retried besides 5xx: request timeout, conflict, too many requests."""
_T = TypeVar("_T")


class DeadlinePassed(Exception):
    """Raised inside the backend when a request's deadline ends a call; never escapes it."""


def time_left(deadline: float | None) -> float | None:
    """Seconds until ``deadline`` (None: no deadline); 0 or less when it has passed."""
    return None if deadline is None else deadline - time.monotonic()


def run_until(call: Callable[[], _T], deadline: float | None) -> _T:
    """``call()``, abandoned at ``deadline``: a daemon thread runs it and is waited on only
    until then. HTTP timeouts bound each read, not a whole body a server trickles out slowly,
    so only this holds a deadline against any server. The abandoned call ends by its own
    timeout; being a daemon thread it never keeps the process alive."""
    if deadline is None:
        return call()
    outcome: list[Any] = []
    done = threading.Event()

    def target() -> None:
        try:
            outcome.append((True, call()))
        except BaseException as error:  # handed to the waiting thread as is
            outcome.append((False, error))
        done.set()

    threading.Thread(target=target, name="stalm-llm-call", daemon=True).start()
    if not done.wait(max(0.0, deadline - time.monotonic())):
        raise DeadlinePassed
    ok, value = outcome[0]
    if not ok:
        raise value
    return cast(_T, value)


@dataclass(frozen=True)
class RetryPolicy:
    """How often and how patiently to retry rate limits, server errors and timeouts.

    The delay before retry ``k`` (0-based) is ``base_delay_s * 2**k`` capped at
    ``max_delay_s``, or the server's ``Retry-After`` when that is longer (still capped).
    """

    max_attempts: int = 4
    base_delay_s: float = 1.0
    max_delay_s: float = 30.0

    def __post_init__(self) -> None:
        if self.max_attempts < 1:
            raise StalmError(f"retry 'max_attempts' must be at least 1, got {self.max_attempts}")

    def delay_s(self, retry_index: int, retry_after_s: float | None = None) -> float:
        delay = self.base_delay_s * (2**retry_index)
        if retry_after_s is not None:
            delay = max(delay, retry_after_s)
        return min(delay, self.max_delay_s)


def retry_after_s(error: openai.APIStatusError) -> float | None:
    value = error.response.headers.get("retry-after")
    try:
        return float(value) if value is not None else None
    except ValueError:
        return None
