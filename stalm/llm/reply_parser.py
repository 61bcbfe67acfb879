"""Read the task plan out of a language model's reply, without ever executing the reply.

The prompt asks for ``plan = [('action_type', 'args_1', ...), ]`` after some prose, and real
replies (the paper's Figures 7-12) bend that format: the list sits in a code fence or not, spans
many lines, carries a ``#`` comment after every tuple, and often closes with a ``]`` that ended
up *inside* the last comment (``('place', 'wine', 'on', 'counter2') # ... the goal ]``). Names
come with stray spaces (``'left _of'``). A small hand-written scanner reads this; ``eval`` and
``ast.literal_eval`` are never used, so a reply can at worst produce errors, never run code.
This module chooses the list and assembles the plan; :mod:`stalm.llm.reply_scanner` reads the
text into raw steps and :mod:`stalm.llm.reply_steps` turns each into an action or an error.

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

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from stalm.domain.actions import DiscreteAction
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.reply_scanner import RawList, Scanner, candidate_starts
from stalm.llm.reply_steps import Interpreter, ParsedStep, StepError, has_operator

MAX_REPLY_CHARS = 65_536
"""How much of a reply is read: far beyond any real reply (the authors' 500 tokens are a few
thousand characters), small enough that an endless or hostile one is read in milliseconds."""


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


def _choose_list(text: str) -> RawList | None:
    """The last list with a known operator in some step; else the last list (see module doc).

    Candidates are read from the last one backwards, each up to where the next one starts, so
    a reply is scanned at most once however many candidates it holds.
    """
    fallback: RawList | None = None
    end = len(text)
    for begin, start in reversed(candidate_starts(text)):
        candidate = Scanner(text, start, end).read_list()
        end = begin
        if has_operator(candidate):
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
    interpreter = Interpreter(vocabulary)
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
