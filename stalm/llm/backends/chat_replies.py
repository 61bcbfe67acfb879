"""Turning a chat completion into :class:`~stalm.llm.backends.base.LLMReply` values.

The decoding side of the chat API client (:mod:`stalm.llm.backends.openai_compatible`): reading
the choices, their finish reasons and the call's token usage out of whatever a server sent
(a body that is no chat completion is one clear error), sharing the usage among the choices,
and turning a JSON-constrained reply back into the paper's text form so one parser reads both.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from stalm.errors import StalmError
from stalm.llm.backends.base import LLMReply, LLMRequest
from stalm.llm.constraints import json_reply_to_plan_text


def chat_replies(
    completion: Any, request: LLMRequest, where: str, latency_s: float, *, json_schema: bool
) -> list[LLMReply]:
    """The choices of one chat completion as replies, or a StalmError naming ``where``.

    ``json_schema``: the output constraint was sent as a JSON schema, so a constrained reply
    is JSON and is turned back into the paper's text form.
    """
    try:
        choices = list(completion.choices)
        texts = [choice.message.content or "" for choice in choices]
        finishes = [choice.finish_reason for choice in choices]
        usage = completion.usage
        prompt_tokens = int(usage.prompt_tokens) if usage else 0
        completion_tokens = int(usage.completion_tokens) if usage else 0
    except (AttributeError, TypeError, ValueError) as error:
        raise StalmError(
            f"{where} answered with something that is not a chat completion "
            f"({type(completion).__name__}: {str(completion)[:80]!r})"
        ) from error
    if not choices:
        raise StalmError(f"{where} returned a chat completion without choices")
    if request.constraint is not None and json_schema:
        texts = [_json_to_text(text) for text in texts]
    shares = _split_tokens(completion_tokens, texts)
    return [
        LLMReply(
            text=text,
            prompt_tokens=prompt_tokens if i == 0 else 0,
            completion_tokens=shares[i],
            latency_s=latency_s,
            finish_reason=finishes[i],
        )
        for i, text in enumerate(texts)
    ]


def _json_to_text(text: str) -> str:
    """The text form of a JSON reply; a malformed one is kept raw for the parser to reject."""
    try:
        return json_reply_to_plan_text(text)
    except StalmError:
        return text


def _split_tokens(total: int, texts: Sequence[str]) -> list[int]:
    """Share a call's completion tokens among its choices in proportion to their length.

    Servers report usage per call, not per choice; the split keeps per-reply numbers
    plausible while their sum stays exactly what the server reported.
    """
    if not texts:
        return []
    lengths = [max(len(text), 1) for text in texts]
    whole = sum(lengths)
    shares = [total * length // whole for length in lengths]
    shares[0] += total - sum(shares)
    return shares
