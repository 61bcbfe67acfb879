"""Scan a language model's reply into raw steps: the tuples of its plan list, as strings only.

The first half of reading a reply (:mod:`stalm.llm.reply_parser` holds the rules: which list,
where it ends, how long a reply is read). Kept apart from the interpretation of the strings
(:mod:`stalm.llm.reply_steps`) because it is the part that must be robust to anything a model
writes: a hand-written cursor that never raises, never evaluates the text, and reads each
character at most once, so its time is linear in the reply's length.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

_PLAN_START = re.compile(r"\bplan\s*=\s*\[", re.IGNORECASE)
_BARE_LIST_START = re.compile(r"\[\s*\(")
_LIST_MARKER = re.compile(r"(?:\d{1,3}\s*[.):]|[-*•])\s*(?=[(\[])")
_BARE_WORD_STOP = frozenset(",()[]'\"#`\n")


ListEnd = Literal["bracket", "comment", "fence", "text", "eof"]


@dataclass(frozen=True)
class RawStep:
    """A tuple as written: its text and strings, or the syntax problem that stopped reading."""

    raw: str
    items: tuple[str, ...]
    problem: str | None = None
    cut_off: bool = False


@dataclass(frozen=True)
class RawList:
    steps: tuple[RawStep, ...]
    end: ListEnd


class Scanner:
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

    def read_list(self) -> RawList:
        """Read the steps of a list whose ``[`` was just consumed (see the module's rules)."""
        steps: list[RawStep] = []
        bracket_in_comment = False
        while True:
            self.skip_blanks(also=",")
            char = self.peek()
            if not char:
                unfinished: ListEnd = "text" if self.bounded else "eof"
                return RawList(tuple(steps), "comment" if bracket_in_comment else unfinished)
            if char == "#":
                bracket_in_comment = "]" in self.rest_of_line()
            elif char == "]":
                self.pos += 1
                return RawList(tuple(steps), "bracket")
            elif char in "([":
                step = self.read_step()
                steps.append(step)
                bracket_in_comment = False
                if step.cut_off:
                    return RawList(tuple(steps), "eof")
            elif char == "`":
                return RawList(tuple(steps), "fence")
            else:
                marker = _LIST_MARKER.match(self.text, self.pos)
                if marker is not None:
                    self.pos = marker.end()
                    continue
                return RawList(tuple(steps), "comment" if bracket_in_comment else "text")

    def read_step(self) -> RawStep:
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
                return RawStep(self.text[start : self.pos].strip(), tuple(items), problem)
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

    def _broken(self, start: int, items: list[str], problem: str, cut_off: bool = False) -> RawStep:
        """Give up on this step: skip the rest of its line so the list can go on after it."""
        if not cut_off:
            self.rest_of_line()
        raw = self.text[start : self.pos].strip()
        return RawStep(raw, tuple(items), problem, cut_off)


def candidate_starts(text: str) -> list[tuple[int, int]]:
    """``(where it starts, just after its [)`` of every ``plan = [``, or of the first bare
    ``[(``."""
    starts = [(match.start(), match.end()) for match in _PLAN_START.finditer(text)]
    if not starts:
        bare = _BARE_LIST_START.search(text)
        if bare is not None:
            starts = [(bare.start(), bare.start() + 1)]
    return starts
