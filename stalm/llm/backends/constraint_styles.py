"""How an OpenAI-compatible server is told the reply's shape, and what to do when it refuses.

Two styles exist (:data:`CONSTRAINT_STYLES`): a JSON schema in ``response_format`` (OpenAI,
vLLM, Ollama, LM Studio) and a GBNF grammar in a ``grammar`` field (llama.cpp's servers). A
server given by URL gets ``json_schema`` unless ``STALM_LLM_CONSTRAINT_STYLE`` says otherwise,
and some servers refuse it: llama.cpp's answers HTTP 500 to a ``json_schema`` response format
it cannot convert. So until one constrained request of a run has been answered, a refusal
(:data:`REFUSALS`) is not retried as a server failure: the other style is tried once, and if
the server takes it, the run keeps it and says so in one line (:func:`switched_notice`); if it
takes neither, one error says what was refused and what to do (:func:`both_refused`).
``stalm llm check --constrained`` tries each style and says which one to set.
"""

from __future__ import annotations

from typing import Literal, cast, get_args

from stalm.errors import StalmError

ConstraintStyle = Literal["json_schema", "gbnf"]
CONSTRAINT_STYLES: tuple[str, ...] = get_args(ConstraintStyle)
CONSTRAINT_STYLE_ENV = "STALM_LLM_CONSTRAINT_STYLE"

REFUSALS = frozenset({400, 422, 500, 501})
"""HTTP statuses with which a server refuses a constraint it does not take (llama.cpp: 500 to
a JSON schema; others: 400 or 422 to a field they do not know); 401/403/404/429 and 503 mean
something else and keep their own handling."""


CONSTRAINT_WORDS = ("schema", "response_format", "grammar", "gbnf")
"""Words a refusal of the constraint names (llama.cpp: 'JSON schema conversion failed'); a 400
or 500 whose message names none of them is some other failure and keeps its own handling."""


def refuses_constraint(status: int, message: str) -> bool:
    """Whether HTTP ``status`` with ``message`` is a server refusing the output constraint."""
    text = message.lower()
    return status in REFUSALS and any(word in text for word in CONSTRAINT_WORDS)


def check_constraint_style(style: str) -> ConstraintStyle:
    """``style`` as a :data:`ConstraintStyle`, or a StalmError listing the valid ones."""
    if style not in CONSTRAINT_STYLES:
        raise StalmError(
            f"unknown constraint style {style!r}; expected one of {', '.join(CONSTRAINT_STYLES)}"
        )
    return cast(ConstraintStyle, style)


def other_style(style: ConstraintStyle) -> ConstraintStyle:
    """The style that is not ``style``."""
    return "gbnf" if style == "json_schema" else "json_schema"


class ConstraintRefused(Exception):
    """A server refused a request's output constraint in ``style`` (HTTP ``status``). Not a
    :class:`StalmError`: the backend catches it and tries the other style."""

    def __init__(self, style: ConstraintStyle, status: int, message: str) -> None:
        super().__init__(style, status, message)
        self.style, self.status, self.message = style, status, message

    def __str__(self) -> str:
        first_line = self.message.strip().splitlines()[0] if self.message.strip() else ""
        detail = f" ({first_line[:120]})" if first_line else ""
        return f"{self.style}: HTTP {self.status}{detail}"


def switched_notice(where: str, refused: ConstraintRefused, taken: ConstraintStyle) -> str:
    """The one line a run says when it moved to the style the server takes."""
    return (
        f"{where} refused the output constraint as {refused}; it takes {taken}, which this run "
        f"uses now (set {CONSTRAINT_STYLE_ENV}={taken} to send it first)"
    )


def both_refused(where: str, first: ConstraintRefused, second: ConstraintRefused) -> StalmError:
    """The error of a server that takes the output constraint in neither style."""
    return StalmError(
        f"{where} refused the output constraint in both styles ({first}; {second}): run "
        "without it (--unconstrained, or llm.constrained=false), or check the server's log"
    )
