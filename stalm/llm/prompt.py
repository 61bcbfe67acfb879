"""The task-planning prompt of the paper (Figure 3, Appendix E Figure 13).

The prompt is a PDDL-*style* text, not strict PDDL: the paper's domain has comments after
``;`` that swallow closing parentheses, untyped parameters, and an ``:init`` written as a
Python list of tuples. We reproduce that wording byte for byte (the golden test compares the
P5 prompt with Figure 13) because the language model was prompted with exactly this text and the
paper's success rates belong to it. A strict PDDL rendering of the same abstraction, for real
planners and validators, lives in :mod:`stalm.llm.pddl`.

The fixed wording sits in one template file per part under ``stalm/llm/templates/`` so a change
of wording is a reviewable text diff; this module only fills in the problem's names and
literals and applies the two ablation switches of the paper's Table 4 (:class:`PromptOptions`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from importlib import resources
from string import Template

from stalm.domain.actions import DIRECTIONS
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.predicates.literals import (
    CANNOT_PREDICATES,
    OCCLUSION_PREDICATES,
    PREDICATE_NAMES,
    SCOPE_PREDICATE,
    GroundLiteral,
)

SHOWN_APART: frozenset[str] = CANNOT_PREDICATES | {SCOPE_PREDICATE}
"""Literals the init never lists: the actions that cannot be done (a section behind
``PromptOptions.cannot_actions``) and the objects relevance-limited predicates covered (a
section whenever they are stated)."""

#: PDDL type names the prompt gives to each kind of entity, in the order of ``(:objects ...)``
#: in Figure 13: movable objects, then doors, then regions.
MOVABLE_TYPE = "movable_object"
DOOR_TYPE = "openable"
REGION_TYPE = "region"

_PICK_SAFETY = "(not (UnsafePick ?subject)) "
_PLACE_SAFETY = "(not (UnsafePlace ?subject ?direction ?reference)) "


@dataclass(frozen=True)
class PromptOptions:
    """The prompt ablations of the paper's Table 4; the defaults are the full STaLM prompt.

    ``occlusion_predicates=False`` removes PickOccludedBy/PlaceOccludedBy everywhere they appear
    (the predicate list, the UnsafePick/UnsafePlace preconditions and derived predicates, and
    the init), leaving the model without geometric information. ``ask_challenges=False`` removes
    the "Possible Challenges" heading from the reply template, i.e. the chain-of-thought step
    that the paper found makes the model respect preconditions.
    """

    occlusion_predicates: bool = True
    ask_challenges: bool = True
    cannot_actions: bool = False
    """Beyond the paper (off for its rows, so their prompt stays Figure 13's): a section
    after the problem listing the actions no motion can do in the state (the
    ``CannotPick``/``CannotPlace`` literals, which the init never shows)."""


@dataclass(frozen=True)
class Prompt:
    """A chat prompt: the system message (reply template) and the user message (the problem)."""

    system: str
    user: str

    @property
    def asks_challenges(self) -> bool:
        """Whether the reply template asks for the "Possible Challenges" section first.

        Read off the system message itself, so it is right for every prompt built from it
        (STaLM's with either ablation, the feedback prompt, SayCan's, which never asks): the
        output constraint must demand that section exactly when the template does.
        """
        return _template("system_challenges") in self.system

    def as_transcript(self) -> str:
        """Both messages under the paper's Figure 13 headings, e.g. to show or diff a prompt."""
        return f"**System prompt**\n\n{self.system}\n\n**User prompt**\n\n{self.user}\n"


@cache
def _template(name: str) -> str:
    """The text of ``templates/<name>.txt`` without its final newline (files end with one)."""
    text = resources.files("stalm.llm").joinpath("templates", f"{name}.txt").read_text("utf-8")
    return text.removesuffix("\n")


def _fill(name: str, **values: str) -> str:
    """Substitute ``${...}`` fields; a field the code forgot raises (a bug, not user input)."""
    return Template(_template(name)).substitute(values)


def system_message(options: PromptOptions) -> str:
    """The task instruction: the expert role and the reply template the parser relies on."""
    challenges = _template("system_challenges") + "\n\n" if options.ask_challenges else ""
    return _fill("system", challenges=challenges)


def domain_text(options: PromptOptions) -> str:
    """The "### Domain ###" part of the user message: header, predicates, actions, derived."""
    occlusion = options.occlusion_predicates
    parts = [
        _template("domain_header"),
        _fill(
            "predicates",
            occlusion_predicates="\n" + _template("predicates_occlusion") if occlusion else "",
        ),
        _fill(
            "actions",
            pick_safety=_PICK_SAFETY if occlusion else "",
            place_safety=_PLACE_SAFETY if occlusion else "",
        ),
    ]
    if occlusion:
        parts.append(_template("derived"))
    return "\n\n".join(parts)


def format_objects(vocabulary: Vocabulary) -> str:
    """``coke - movable_object ... kitchen_door - openable counter1 - region `` (Figure 13)."""
    typed = (
        [(name, MOVABLE_TYPE) for name in vocabulary.movables]
        + [(name, DOOR_TYPE) for name in vocabulary.doors]
        + [(name, REGION_TYPE) for name in vocabulary.regions]
    )
    return "".join(f"{name} - {kind} " for name, kind in typed)


def format_init(init: Sequence[GroundLiteral]) -> str:
    """The init as a Python-style list of tuples: ``[('HandAvailable', ''), ...]``."""
    return "[" + ", ".join(_python_tuple(literal.as_tuple()) for literal in init) + "]"


def format_goal(goal: Sequence[GroundLiteral]) -> str:
    """Goal literals as s-expressions, each followed by a space, as Figure 13 prints them."""
    return "".join(f"({' '.join((literal.name, *literal.args))}) " for literal in goal)


def cannot_action(literal: GroundLiteral) -> str:
    """``CannotPick(plate)`` as the action it rules out, in the reply's plan form:
    ``pick(plate)``, ``place(coke, behind_of, beef_grill)``."""
    operator = "pick" if literal.name == "CannotPick" else "place"
    return f"{operator}({', '.join(literal.args)})"


def _python_tuple(items: tuple[str, ...]) -> str:
    """A tuple of strings written as Python would, without a 1-tuple's trailing comma."""
    return "(" + ", ".join(repr(item) for item in items) + ")"


def _check_literals(vocabulary: Vocabulary, literals: Sequence[GroundLiteral], field: str) -> None:
    """Refuse literals the model could not resolve: unknown predicates or names.

    A prompt that mentions a name absent from ``(:objects ...)`` confuses the model (Figure 9
    shows GPT-4 deciding that the goal region "is not declared" and planning for another one),
    so this is an error of the problem, reported with the offending literal.
    """
    known = set(vocabulary.all_names) | set(DIRECTIONS)
    for literal in literals:
        if literal.name not in PREDICATE_NAMES and literal.name not in SHOWN_APART:
            raise StalmError(f"{field}: unknown predicate {literal.name!r} in {literal}")
        unknown = [arg for arg in literal.args if arg not in known]
        if unknown:
            raise StalmError(f"{field}: unknown name {unknown[0]!r} in {literal}")


def build_prompt(
    vocabulary: Vocabulary,
    init: Sequence[GroundLiteral],
    goal: Sequence[GroundLiteral],
    options: PromptOptions = PromptOptions(),
) -> Prompt:
    """The prompt for one state: the paper's domain, the problem's objects, init and goal.

    ``init`` is printed in the order given (the caller decides the order; Figure 13 lists
    HandAvailable, then AtPosition, then occlusions). With ``options.occlusion_predicates``
    off, occlusion literals are dropped from it; the actions that cannot be done
    (``CannotPick``/``CannotPlace``) never show in it, but as a section of their own with
    ``options.cannot_actions``; nor do the objects relevance-limited predicates covered
    (``OcclusionComputed``), which get a section whenever occlusion is shown. Raises
    :class:`StalmError` for a literal with an unknown predicate or name.
    """
    _check_literals(vocabulary, init, "init")
    _check_literals(vocabulary, goal, "goal")
    cannot = [literal for literal in init if literal.name in CANNOT_PREDICATES]
    scope = sorted(literal.args[0] for literal in init if literal.name == SCOPE_PREDICATE)
    init = [literal for literal in init if literal.name not in SHOWN_APART]
    if not options.occlusion_predicates:
        init = [literal for literal in init if literal.name not in OCCLUSION_PREDICATES]
    problem = _fill(
        "problem",
        objects=format_objects(vocabulary),
        init=format_init(init),
        goal=format_goal(goal),
    )
    parts = [domain_text(options), problem]
    if options.cannot_actions and cannot:
        parts.append(_fill("cannot", actions=", ".join(cannot_action(c) for c in cannot)))
    if scope and options.occlusion_predicates:
        parts.append(_fill("scope", objects=", ".join(scope)))
    user = "\n\n".join([*parts, _template("request")])
    return Prompt(system=system_message(options), user=user)
