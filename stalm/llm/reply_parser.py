"""Read the task plan out of a language model's reply, without ever executing the reply.

The prompt asks for ``plan = [('action_type', 'args_1', ...), ]`` after some prose, and real
replies (the paper's Figures 7-12) bend that format: the list sits in a code fence or not, spans
many lines, carries a ``#`` comment after every tuple, and often closes with a ``]`` that ended
up *inside* the last comment (``('place', 'wine', 'on', 'counter2') # ... the goal ]``). Names
come with stray spaces (``'left _of'``). A small hand-written scanner reads this; ``eval`` and
``ast.literal_eval`` are never used, so a reply can at worst produce errors, never run code.

Decisions (each is a policy the planner relies on, so it is written down here):

* **Which list.** Every ``plan = [`` is a candidate; the last one that holds a step with a known
  operator wins (a model that revises its plan writes the final one last; an echo of the
  template's ``('action_type', ...)`` is skipped). Without any ``plan = [``, the first ``[``
  directly followed by ``(`` is read.
* **Where the list ends.** At its ``]``; or after the last step if a ``#`` comment after it
  holds a ``]`` (Figures 8, 10-12); or at a closing code fence. A list followed by prose
  without any ``]`` is read up to the prose and the reply gets a ``reason``. A reply that ends
  inside the list was cut off (e.g. by ``max_tokens``): its plan is the complete steps before
  the cut (a step cut in the middle is dropped), as the authors' parser kept every complete
  parenthesised group, and the reply is marked ``truncated`` with a ``reason``, so a caller
  can tell the model's finished plan from the start of an unfinished one.
* **Near misses** are normalised and each fix is noted on the step: case, spaces, hyphens and
  underscores are ignored when matching names (``'left _of'``, ``'Beef Grill'``,
  ``'leftof'``); a bare direction means the relation (``'left'`` -> ``left_of``, ``'in front
  of'`` -> ``front_of``); a name that is the first word of exactly one name of the expected
  kind stands for it (Figure 7's ``'shelf'`` -> ``shelf_lower``); ``pick_up``/``pickup`` mean
  pick; empty strings (mimicking the prompt's ``('HandAvailable', '')``) are dropped.
* **Bad steps** (syntax, unknown operator or name, wrong arity, wrong kind of entity such as
  placing ``on`` a movable or opening a movable) become :class:`StepError` values, never
  exceptions. The plan is the valid prefix before the first bad step, as the authors' code cut
  the plan at the first unknown name: later steps were chosen for the state the bad step would
  have produced. All steps and all errors are kept for diagnosis.
* **Bounded time.** Only the first :data:`MAX_REPLY_CHARS` characters are read (a reply of
  500 tokens is a few thousand; anything longer is noted in ``reason``), and each candidate
  list is read only up to where the next ``plan = [`` starts, so no text is scanned twice and
  the time is linear in the reply's length whatever the reply holds.
* The parser checks names and kinds only. State preconditions (an empty hand before pick,
  an occlusion) are the domain's business, because a plan that breaks them is still the
  model's plan and the search uses it as such.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal

from stalm.domain.actions import DIRECTIONS, Direction, DiscreteAction, Open, Pick, Place
from stalm.domain.vocabulary import Vocabulary

ErrorKind = Literal["syntax", "unknown_operator", "unknown_name", "arity", "wrong_kind"]

MAX_REPLY_CHARS = 65_536
"""How much of a reply is read: far beyond any real reply (the authors' 500 tokens are a few
thousand characters), small enough that an endless or hostile one is read in milliseconds."""

_PLAN_START = re.compile(r"\bplan\s*=\s*\[", re.IGNORECASE)
_BARE_LIST_START = re.compile(r"\[\s*\(")
_LIST_MARKER = re.compile(r"(?:\d{1,3}\s*[.):]|[-*•])\s*(?=[(\[])")
_SEPARATORS = re.compile(r"[\s\-]+")
_BARE_WORD_STOP = frozenset(",()[]'\"#`\n")
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


@dataclass(frozen=True)
class ParsedReply:
    """The plan read from one reply, with every step and error, and why it is not clean.

    ``plan`` holds the valid prefix of the steps (empty for garbage or empty replies; for a
    reply cut off inside the list, the complete steps before the cut). ``reason`` is None for a
    cleanly parsed reply and otherwise one sentence saying what went wrong first.
    ``truncated`` is true when the reply ends inside the plan list: the model did not finish
    writing its plan, so ``plan`` is only its beginning.
    """

    plan: tuple[DiscreteAction, ...]
    steps: tuple[ParsedStep, ...]
    errors: tuple[StepError, ...]
    reason: str | None
    truncated: bool = False

    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict: plan as lists of strings, steps, errors (index, raw, message)."""
        return {
            "plan": [list(action.as_tuple()) for action in self.plan],
            "steps": [step.to_json() for step in self.steps],
            "errors": [error.to_json() for error in self.errors],
            "reason": self.reason,
            "truncated": self.truncated,
        }


# ---------------------------------------------------------------------------------------------
# Scanning: text -> raw steps (strings only, no meaning yet)


ListEnd = Literal["bracket", "comment", "fence", "text", "eof"]


@dataclass(frozen=True)
class _RawStep:
    """A tuple as written: its text and strings, or the syntax problem that stopped reading."""

    raw: str
    items: tuple[str, ...]
    problem: str | None = None
    cut_off: bool = False


@dataclass(frozen=True)
class _RawList:
    steps: tuple[_RawStep, ...]
    end: ListEnd


class _Scanner:
    """A cursor over ``text[pos:end]``; each method consumes one construct and never raises.

    ``end`` is where the next candidate list starts (or the reply's end): a list is never read
    into the next one, which keeps the whole parse linear. Reaching an ``end`` that is not the
    reply's end is not a cut-off reply: the list just stops there, like one followed by text.
    """

    def __init__(self, text: str, pos: int, end: int | None = None) -> None:
        self.text = text
        self.pos = pos
        self.end = len(text) if end is None else end
        self.bounded = self.end < len(text)

    def at_end(self) -> bool:
        return self.pos >= self.end

    def peek(self) -> str:
        return self.text[self.pos] if self.pos < self.end else ""

    def skip_blanks(self, also: str = "") -> None:
        """Skip whitespace and any of the characters in ``also`` (separating commas)."""
        text, end = self.text, self.end
        while self.pos < end and (text[self.pos].isspace() or text[self.pos] in also):
            self.pos += 1

    def rest_of_line(self) -> str:
        """Consume up to (not including) the next newline and return what was consumed."""
        end = self.text.find("\n", self.pos, self.end)
        end = self.end if end < 0 else end
        line = self.text[self.pos : end]
        self.pos = end
        return line

    def read_list(self) -> _RawList:
        """Read the steps of a list whose ``[`` was just consumed (see the module's rules)."""
        steps: list[_RawStep] = []
        bracket_in_comment = False
        while True:
            self.skip_blanks(also=",")
            char = self.peek()
            if not char:
                unfinished: ListEnd = "text" if self.bounded else "eof"
                return _RawList(tuple(steps), "comment" if bracket_in_comment else unfinished)
            if char == "#":
                bracket_in_comment = "]" in self.rest_of_line()
            elif char == "]":
                self.pos += 1
                return _RawList(tuple(steps), "bracket")
            elif char in "([":
                step = self.read_step()
                steps.append(step)
                bracket_in_comment = False
                if step.cut_off:
                    return _RawList(tuple(steps), "eof")
            elif char == "`":
                return _RawList(tuple(steps), "fence")
            else:
                marker = _LIST_MARKER.match(self.text, self.pos)
                if marker is not None:
                    self.pos = marker.end()
                    continue
                return _RawList(tuple(steps), "comment" if bracket_in_comment else "text")

    def read_step(self) -> _RawStep:
        """Read one ``(...)`` (or ``[...]``) of strings or bare words; recover at line end."""
        start = self.pos
        closer = ")" if self.text[start] == "(" else "]"
        self.pos += 1
        items: list[str] = []
        while True:
            self.skip_blanks(also=",")
            char = self.peek()
            if not char and self.bounded:
                return self._broken(start, items, "the step is not closed")
            if not char:
                return self._broken(start, items, "the step is cut off", cut_off=True)
            if char in ")]":
                self.pos += 1
                problem = None if char == closer else f"the step closes with {char!r}"
                return _RawStep(self.text[start : self.pos].strip(), tuple(items), problem)
            if char == "#":
                self.rest_of_line()
            elif char in "'\"":
                value = self.read_string(char)
                if value is None:
                    cut_off = self.at_end() and not self.bounded
                    return self._broken(start, items, "unterminated string", cut_off=cut_off)
                items.append(value)
            elif char in "([`":
                return self._broken(start, items, f"unexpected {char!r} inside the step")
            else:
                items.append(self.read_bare_word())

    def read_string(self, quote: str) -> str | None:
        """A quoted string on one line (backslash escapes the next character), or None."""
        chars: list[str] = []
        pos = self.pos + 1
        text, end = self.text, self.end
        while pos < end:
            char = text[pos]
            if char == "\\" and pos + 1 < end and text[pos + 1] != "\n":
                chars.append(text[pos + 1])
                pos += 2
                continue
            if char == quote:
                self.pos = pos + 1
                return "".join(chars)
            if char == "\n":
                break
            chars.append(char)
            pos += 1
        self.pos = pos
        return None

    def read_bare_word(self) -> str:
        """An unquoted item such as ``pick`` in ``(pick, coke)``: up to the next delimiter."""
        start = self.pos
        while self.pos < self.end and self.text[self.pos] not in _BARE_WORD_STOP:
            self.pos += 1
        return self.text[start : self.pos].strip()

    def _broken(
        self, start: int, items: list[str], problem: str, cut_off: bool = False
    ) -> _RawStep:
        """Give up on this step: skip the rest of its line so the list can go on after it."""
        if not cut_off:
            self.rest_of_line()
        raw = self.text[start : self.pos].strip()
        return _RawStep(raw, tuple(items), problem, cut_off)


def _candidate_starts(text: str) -> list[tuple[int, int]]:
    """``(where it starts, just after its [)`` of every ``plan = [``, or of the first bare
    ``[(``."""
    starts = [(match.start(), match.end()) for match in _PLAN_START.finditer(text)]
    if not starts:
        bare = _BARE_LIST_START.search(text)
        if bare is not None:
            starts = [(bare.start(), bare.start() + 1)]
    return starts


# ---------------------------------------------------------------------------------------------
# Interpretation: raw steps -> actions or errors


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


class _Interpreter:
    """Turns raw steps into actions against one vocabulary; notes and errors are values."""

    def __init__(self, vocabulary: Vocabulary) -> None:
        self.vocabulary = vocabulary
        by_key: dict[str, list[str]] = {}
        for name in vocabulary.all_names:
            by_key.setdefault(_key(name), []).append(name)
        self.by_key = by_key

    def step(self, index: int, raw: _RawStep) -> ParsedStep:
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


# ---------------------------------------------------------------------------------------------
# The public entry point


def _has_operator(candidate: _RawList) -> bool:
    return any(
        step.items and _OPERATOR_ALIASES.get(_key(step.items[0])) is not None
        for step in candidate.steps
    )


def _choose_list(text: str) -> _RawList | None:
    """The last list with a known operator in some step; else the last list (see module doc).

    Candidates are read from the last one backwards, each up to where the next one starts, so
    a reply is scanned at most once however many candidates it holds.
    """
    fallback: _RawList | None = None
    end = len(text)
    for begin, start in reversed(_candidate_starts(text)):
        candidate = _Scanner(text, start, end).read_list()
        end = begin
        if _has_operator(candidate):
            return candidate
        fallback = fallback or candidate
    return fallback


def _valid_prefix(steps: Iterable[ParsedStep]) -> tuple[DiscreteAction, ...]:
    plan: list[DiscreteAction] = []
    for step in steps:
        if step.action is None:
            break
        plan.append(step.action)
    return tuple(plan)


def parse_reply(text: str, vocabulary: Vocabulary) -> ParsedReply:
    """The task plan in ``text``, read against the problem's names; never raises.

    See the module docstring for how the list is found, where it ends, which near misses are
    normalised and why the plan is the valid prefix of the steps.
    """
    if not text.strip():
        return ParsedReply((), (), (), "the reply is empty")
    if len(text) > MAX_REPLY_CHARS:
        parsed = parse_reply(text[:MAX_REPLY_CHARS], vocabulary)
        cut = f"only the first {MAX_REPLY_CHARS} of the reply's {len(text)} characters were read"
        why = cut if parsed.reason is None else f"{parsed.reason}; {cut}"
        return ParsedReply(parsed.plan, parsed.steps, parsed.errors, why)
    chosen = _choose_list(text)
    if chosen is None:
        return ParsedReply((), (), (), "no plan list (plan = [...]) in the reply")
    interpreter = _Interpreter(vocabulary)
    steps = tuple(interpreter.step(index, raw) for index, raw in enumerate(chosen.steps))
    errors = tuple(step.error for step in steps if step.error is not None)
    if chosen.end == "eof":
        prefix = _valid_prefix(steps)
        cut = "the reply ends inside the plan list (cut off?)"
        if prefix:
            cut += f"; kept its first {len(prefix)} complete step(s)"
        return ParsedReply(prefix, steps, errors, cut, truncated=True)
    if not steps:
        empty = "the plan list is empty" if chosen.end != "text" else "the plan list has no steps"
        return ParsedReply((), steps, errors, empty)
    plan = _valid_prefix(steps)
    reason: str | None = None
    if errors:
        first = errors[0]
        reason = (
            f"plan cut to its first {len(plan)} step(s): step index {first.index} "
            f"is invalid ({first.message})"
        )
        if len(errors) > 1:
            reason += f"; {len(errors) - 1} more invalid step(s)"
    elif chosen.end == "text":
        reason = "the plan list is not closed with ']'; read up to the text after it"
    return ParsedReply(plan, steps, errors, reason)
