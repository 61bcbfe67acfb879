"""Interpret the raw steps of a reply's plan list against one problem's names: each becomes an
action, with a note for every near miss normalised on the way, or a :class:`StepError`.

The second half of reading a reply (:mod:`stalm.llm.reply_parser` holds the rules; the raw
steps come from :mod:`stalm.llm.reply_scanner`). Kept apart from the scanning because it is
where the problem's vocabulary enters: what counts as an operator, a direction, a name of the
right kind, and which near misses are read as which name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Literal

from stalm.domain.actions import DIRECTIONS, Direction, DiscreteAction, Open, Pick, Place
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.reply_scanner import RawList, RawStep

ErrorKind = Literal["syntax", "unknown_operator", "unknown_name", "arity", "wrong_kind"]

_SEPARATORS = re.compile(r"[\s\-]+")
_OPERATOR_ALIASES: dict[str, str] = {
    "pick": "pick",
    "pickup": "pick",
    "place": "place",
    "open": "open",
}
_DIRECTION_ALIASES: dict[str, Direction] = {
    **{direction.replace("_", ""): direction for direction in DIRECTIONS},
    "left": "left_of",
    "right": "right_of",
    "front": "front_of",
    "infrontof": "front_of",
    "infront": "front_of",
    "behind": "behind_of",
    "ontopof": "on",
    "onto": "on",
}
_ARITY: dict[str, int] = {"pick": 1, "place": 3, "open": 1}
_SIGNATURE: dict[str, str] = {
    "pick": "('pick', object)",
    "place": "('place', object, direction, reference)",
    "open": "('open', door)",
}
_KIND_WORDS: dict[str, str] = {"movable": "movable object", "region": "region", "door": "door"}


@dataclass(frozen=True)
class StepError:
    """Why one step of the reply's plan list is not an action of this problem.

    ``index`` is the step's 0-based position in the list and ``raw`` its text as written.
    """

    index: int
    raw: str
    kind: ErrorKind
    message: str

    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict with the index, raw text, error kind and message."""
        return {"index": self.index, "raw": self.raw, "kind": self.kind, "message": self.message}


@dataclass(frozen=True)
class ParsedStep:
    """One entry of the plan list: its text, the strings read, and the action or the error.

    Exactly one of ``action`` and ``error`` is set. ``notes`` say which near misses were
    normalised to reach ``action`` (e.g. ``"'left _of' read as 'left_of'"``).
    """

    index: int
    raw: str
    items: tuple[str, ...]
    action: DiscreteAction | None
    error: StepError | None
    notes: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict; the action as a list of strings, or null."""
        return {
            "index": self.index,
            "raw": self.raw,
            "items": list(self.items),
            "action": list(self.action.as_tuple()) if self.action is not None else None,
            "error": self.error.to_json() if self.error is not None else None,
            "notes": list(self.notes),
        }


def _key(word: str) -> str:
    """Case, spacing, hyphens and underscores do not distinguish names for the model."""
    return _normal(word).replace("_", "")


def _normal(word: str) -> str:
    """Lower case, runs of spaces/hyphens as one underscore, no underscore runs or edges."""
    word = _SEPARATORS.sub("_", word.strip().strip("`*.:").lower())
    return re.sub(r"_+", "_", word).strip("_")


def _expected_kind(operator: str, position: int, direction: Direction) -> str:
    """The kind of entity an argument must name; place's reference depends on ``on``."""
    if operator == "open":
        return "door"
    if operator == "place" and position == 2:
        return "region" if direction == "on" else "movable"
    return "movable"


def _kind_message(
    operator: str, position: int, direction: Direction, name: str, kind: str | None
) -> str:
    """Say which entity was of the wrong kind for which role, and what the role needs."""
    what = _KIND_WORDS.get(kind or "", "entity")
    if operator == "pick":
        return f"cannot pick {what} {name!r}: only movable objects are picked"
    if operator == "open":
        return f"cannot open {what} {name!r}: only doors are opened"
    if position == 0:
        return f"cannot place {what} {name!r}: only movable objects are placed"
    if direction == "on":
        return f"cannot place 'on' {what} {name!r}: 'on' needs a region"
    return f"cannot place {direction!r} {what} {name!r}: {direction!r} needs a movable object"


@dataclass(frozen=True)
class _Resolved:
    value: str | None
    note: str | None = None
    error: str | None = None


class Interpreter:
    """Turns raw steps into actions against one vocabulary; notes and errors are values."""

    def __init__(self, vocabulary: Vocabulary) -> None:
        self.vocabulary = vocabulary
        by_key: dict[str, list[str]] = {}
        for name in vocabulary.all_names:
            by_key.setdefault(_key(name), []).append(name)
        self.by_key = by_key

    def step(self, index: int, raw: RawStep) -> ParsedStep:
        """The action a raw step names, or the first reason it names none."""
        notes: list[str] = []

        def fail(kind: ErrorKind, message: str) -> ParsedStep:
            error = StepError(index, raw.raw, kind, message)
            return ParsedStep(index, raw.raw, raw.items, None, error, tuple(notes))

        if raw.problem is not None:
            return fail("syntax", raw.problem)
        items = [item for item in raw.items if item.strip()]
        if len(items) < len(raw.items):
            notes.append("empty strings ignored")
        if not items:
            return fail("syntax", "the step is empty")
        operator = _OPERATOR_ALIASES.get(_key(items[0]))
        if operator is None:
            return fail("unknown_operator", f"unknown operator {items[0]!r}")
        if operator != items[0]:
            notes.append(f"{items[0]!r} read as {operator!r}")
        args = items[1:]
        if len(args) != _ARITY[operator]:
            return fail(
                "arity",
                f"{operator} takes {_ARITY[operator]} argument(s) as {_SIGNATURE[operator]}, "
                f"got {len(args)}",
            )
        direction: Direction = "on"
        if operator == "place":
            read = _DIRECTION_ALIASES.get(_key(args[1]))
            if read is None:
                return fail("unknown_name", f"unknown direction {args[1]!r}")
            if read != args[1]:
                notes.append(f"{args[1]!r} read as {read!r}")
            direction = read
        names: list[str] = []
        for position, arg in enumerate(args):
            if operator == "place" and position == 1:
                names.append(direction)
                continue
            expected = _expected_kind(operator, position, direction)
            resolved = self.name(arg, expected)
            if resolved.value is None:
                return fail("unknown_name", resolved.error or f"unknown name {arg!r}")
            if resolved.note is not None:
                notes.append(resolved.note)
            kind = self.vocabulary.kind_of(resolved.value)
            if kind != expected:
                message = _kind_message(operator, position, direction, resolved.value, kind)
                return fail("wrong_kind", message)
            names.append(resolved.value)
        action: DiscreteAction
        if operator == "pick":
            action = Pick(names[0])
        elif operator == "open":
            action = Open(names[0])
        elif names[0] == names[2]:
            return fail("wrong_kind", f"cannot place {names[0]!r} relative to itself")
        else:
            action = Place(names[0], direction, names[2])
        return ParsedStep(index, raw.raw, raw.items, action, None, tuple(notes))

    def name(self, word: str, expected: str) -> _Resolved:
        """Exact name; else the one name equal up to case/spacing; else a unique first word."""
        if self.vocabulary.kind_of(word) is not None:
            return _Resolved(word)
        same = self.by_key.get(_key(word), [])
        if len(same) == 1:
            return _Resolved(same[0], f"{word!r} read as {same[0]!r}")
        normal = _normal(word)
        if normal and len(same) == 0:
            names = self.names_of_kind(expected)
            longer = [name for name in names if _normal(name).startswith(normal + "_")]
            if len(longer) == 1:
                return _Resolved(longer[0], f"{word!r} read as {longer[0]!r}")
            if len(longer) > 1:
                options = ", ".join(repr(name) for name in longer)
                return _Resolved(None, error=f"ambiguous name {word!r} (could be {options})")
        if len(same) > 1:
            options = ", ".join(repr(name) for name in same)
            return _Resolved(None, error=f"ambiguous name {word!r} (could be {options})")
        return _Resolved(None, error=f"unknown name {word!r}")

    def names_of_kind(self, kind: str) -> tuple[str, ...]:
        if kind == "movable":
            return self.vocabulary.movables
        if kind == "region":
            return self.vocabulary.regions
        return self.vocabulary.doors


def has_operator(candidate: RawList) -> bool:
    """Does a step of ``candidate`` start with a known operator (unlike the template's echo)?"""
    return any(
        step.items and _OPERATOR_ALIASES.get(_key(step.items[0])) is not None
        for step in candidate.steps
    )
