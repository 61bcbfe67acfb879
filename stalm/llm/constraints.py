"""Output constraints that admit only the paper's reply template with the problem's own names.

The system prompt of the paper (Figure 13) asks for a reply of this shape::

    ## Possible Challenges for unachieved goals based on current state ##
    1. ...
    ## Plan for unachieved goals ##
    plan = [('pick', 'coke'), ('place', 'coke', 'on', 'counter1'), ...]

A strong model follows it unaided; a small local one often does not (wrong headers, invented
objects, no closing bracket, or it never stops). Constrained decoding makes every sample
well-formed and keeps it to the problem's vocabulary, so the search spends its budget on
geometry rather than on unparseable text. Two forms are built from one :class:`Vocabulary`:

* a GBNF grammar for llama.cpp (the embedded backend and llama.cpp's server), and
* a JSON schema for servers with structured output (OpenAI, vLLM, Ollama), whose JSON reply
  :func:`json_reply_to_plan_text` turns back into the text form, so one parser reads both.

Both are bounded (challenge lines, their length, plan steps) so that even a tiny model that
would ramble forever reaches the end of the grammar and stops.

The challenges section is part of the constraint only when the prompt asks for it
(``challenges=True``, the full STaLM prompt). For Table 4's "no challenges" ablation and
for SayCan's template, the constraint admits the plan section alone: a grammar that still
forced the model to write challenges would measure the full prompt under another name.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any

from stalm.domain.actions import RELATIVE_DIRECTIONS
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError

CHALLENGES_HEADER = "## Possible Challenges for unachieved goals based on current state ##"
PLAN_HEADER = "## Plan for unachieved goals ##"
CONSTRAINT_NAME = "stalm_reply"


@dataclass(frozen=True)
class OutputConstraint:
    """A restriction of what the model may write, in the two forms servers understand.

    llama.cpp (embedded, or its server) reads a GBNF grammar; OpenAI and servers that follow
    its structured-output API read a JSON schema. Both are built together from one problem's
    vocabulary (:func:`stalm.llm.constraints.build_constraint`) so a backend can pick the form
    it supports. The schema is kept as canonical JSON text so the value stays hashable and its
    fingerprint is stable across processes and machines (the reply cache keys on it).
    """

    name: str
    gbnf: str
    json_schema_text: str

    def json_schema(self) -> dict[str, Any]:
        """The JSON schema as a fresh dict (callers may mutate it)."""
        schema: dict[str, Any] = json.loads(self.json_schema_text)
        return schema

    @property
    def fingerprint(self) -> str:
        """A short stable digest of both forms: the cache's notion of "same constraint"."""
        digest = hashlib.sha256()
        for part in (self.name, self.gbnf, self.json_schema_text):
            digest.update(part.encode("utf-8"))
            digest.update(b"\x00")
        return digest.hexdigest()[:16]


# Free text may use printable ASCII except '#', so a challenge line cannot open a new section.
_GBNF_TEXT_CHAR = r"[\x20-\x22\x24-\x7E]"


@dataclass(frozen=True)
class ConstraintLimits:
    """Bounds that keep constrained replies short enough for a tiny model to finish.

    The defaults fit a 20-step horizon (the paper's H) and about 500 tokens in all.
    """

    max_challenge_lines: int = 4
    max_line_chars: int = 160
    max_steps: int = 20

    def __post_init__(self) -> None:
        if not 1 <= self.max_challenge_lines <= 9:
            raise StalmError(
                f"constraint limit 'max_challenge_lines' must be 1..9, got "
                f"{self.max_challenge_lines}"
            )
        if self.max_line_chars < 1:
            raise StalmError(
                f"constraint limit 'max_line_chars' must be positive, got {self.max_line_chars}"
            )
        if self.max_steps < 1:
            raise StalmError(f"constraint limit 'max_steps' must be positive, got {self.max_steps}")

    @property
    def max_challenge_chars(self) -> int:
        """The JSON form's bound on the challenges string: the text form's lines, joined."""
        return self.max_challenge_lines * (self.max_line_chars + 4)


def _check_vocabulary(vocabulary: Vocabulary) -> None:
    if not vocabulary.movables:
        raise StalmError("cannot constrain replies for a problem without movable objects")
    for name in vocabulary.all_names:
        if not name or any(ch in name for ch in "'\"\\\n"):
            raise StalmError(
                f"entity name {name!r} cannot appear in a plan reply (empty, or has a quote, "
                "backslash or newline)"
            )


def _gbnf_literal(text: str) -> str:
    """A GBNF string literal for ``text`` (names are checked to need no escaping)."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _gbnf_alternatives(words: tuple[str, ...]) -> str:
    """Alternatives matching each word in single quotes, as the plan tuples write them."""
    return " | ".join(_gbnf_literal(f"'{word}'") for word in words)


def build_gbnf(
    vocabulary: Vocabulary, limits: ConstraintLimits | None = None, *, challenges: bool = True
) -> str:
    """A GBNF grammar admitting only the reply template with this problem's names.

    PLACE relative to an object never names the held object as its own reference, and
    PLACE ``on`` takes a region, so every step the grammar admits is a grounded action of
    :meth:`Vocabulary.all_discrete_actions`. With ``challenges=False`` the reply starts with
    the plan header: no challenges section is admitted.
    """
    limits = limits or ConstraintLimits()
    _check_vocabulary(vocabulary)
    movables = vocabulary.movables
    step_kinds = ["pick"]
    if vocabulary.regions or len(movables) > 1:
        step_kinds.append("place")
    if vocabulary.doors:
        step_kinds.append("open")

    plan = f'"plan = [" step (step-sep step){{0,{limits.max_steps - 1}}} "]"'
    if challenges:
        lines = [
            "root ::= challenges-head challenge-line"
            f"{{1,{limits.max_challenge_lines}}} plan-head {plan}",
            f"challenges-head ::= {_gbnf_literal(CHALLENGES_HEADER + chr(10))}",
            f'challenge-line ::= [1-9] ". " text-char{{1,{limits.max_line_chars}}} "\\n"',
            f"text-char ::= {_GBNF_TEXT_CHAR}",
            f"plan-head ::= {_gbnf_literal(chr(10) + PLAN_HEADER + chr(10))}",
        ]
    else:
        lines = [
            f"root ::= plan-head {plan}",
            f"plan-head ::= {_gbnf_literal(PLAN_HEADER + chr(10))}",
        ]
    lines += [
        'step-sep ::= "," [ \\n]?',
        "step ::= " + " | ".join(step_kinds),
        'pick ::= "(\'pick\', " movable ")"',
        f"movable ::= {_gbnf_alternatives(movables)}",
    ]
    if "place" in step_kinds:
        place_rules = [f"place-{i}" for i in range(len(movables))]
        lines.append("place ::= " + " | ".join(place_rules))
        if vocabulary.regions:
            lines.append(f"region ::= {_gbnf_alternatives(vocabulary.regions)}")
        if len(movables) > 1:
            lines.append(f"rel-dir ::= {_gbnf_alternatives(RELATIVE_DIRECTIONS)}")
        for i, obj in enumerate(movables):
            destinations = []
            if vocabulary.regions:
                destinations.append(_gbnf_literal("'on', ") + " region")
            if len(movables) > 1:
                destinations.append(f'rel-dir ", " others-{i}')
                others = tuple(m for m in movables if m != obj)
                lines.append(f"others-{i} ::= {_gbnf_alternatives(others)}")
            head = _gbnf_literal(f"('place', '{obj}', ")
            lines.append(f'place-{i} ::= {head} ({" | ".join(destinations)}) ")"')
    if "open" in step_kinds:
        lines.append('open ::= "(\'open\', " door ")"')
        lines.append(f"door ::= {_gbnf_alternatives(vocabulary.doors)}")
    return "\n".join(lines) + "\n"


def _tuple_schema(*positions: dict[str, Any]) -> dict[str, Any]:
    return {
        "type": "array",
        "prefixItems": list(positions),
        "minItems": len(positions),
        "maxItems": len(positions),
    }


def build_json_schema(
    vocabulary: Vocabulary, limits: ConstraintLimits | None = None, *, challenges: bool = True
) -> dict[str, Any]:
    """A JSON schema ``{"challenges": str, "plan": [[op, args...], ...]}`` with enums
    (``{"plan": ...}`` alone with ``challenges=False``).

    Each step is a JSON array in the order of the text form's tuples (``["place", "coke",
    "on", "counter1"]``), described with ``prefixItems`` (JSON Schema 2020-12), which vLLM,
    Ollama and llama.cpp's ``json_schema`` support. OpenAI's *strict* structured output does
    not accept ``prefixItems``, so the OpenAI-compatible backend sends the schema non-strict
    unless told otherwise.
    """
    limits = limits or ConstraintLimits()
    _check_vocabulary(vocabulary)
    movables = list(vocabulary.movables)
    steps: list[dict[str, Any]] = [_tuple_schema({"const": "pick"}, {"enum": movables})]
    if vocabulary.regions:
        steps.append(
            _tuple_schema(
                {"const": "place"},
                {"enum": movables},
                {"const": "on"},
                {"enum": list(vocabulary.regions)},
            )
        )
    for obj in movables:
        others = [m for m in movables if m != obj]
        if others:
            steps.append(
                _tuple_schema(
                    {"const": "place"},
                    {"const": obj},
                    {"enum": list(RELATIVE_DIRECTIONS)},
                    {"enum": others},
                )
            )
    if vocabulary.doors:
        steps.append(_tuple_schema({"const": "open"}, {"enum": list(vocabulary.doors)}))
    properties: dict[str, Any] = {}
    if challenges:
        properties["challenges"] = {"type": "string", "maxLength": limits.max_challenge_chars}
    properties["plan"] = {
        "type": "array",
        "minItems": 1,
        "maxItems": limits.max_steps,
        "items": {"anyOf": steps},
    }
    return {
        "title": CONSTRAINT_NAME,
        "type": "object",
        "properties": properties,
        "required": list(properties),
        "additionalProperties": False,
    }


def build_constraint(
    vocabulary: Vocabulary, limits: ConstraintLimits | None = None, *, challenges: bool = True
) -> OutputConstraint:
    """Both forms of the reply constraint for one problem, ready to put in an LLMRequest.

    ``challenges`` must match the prompt (:attr:`stalm.llm.prompt.Prompt.asks_challenges`).
    """
    limits = limits or ConstraintLimits()
    schema = build_json_schema(vocabulary, limits, challenges=challenges)
    return OutputConstraint(
        name=CONSTRAINT_NAME,
        gbnf=build_gbnf(vocabulary, limits, challenges=challenges),
        json_schema_text=json.dumps(schema, sort_keys=True, separators=(",", ":")),
    )


def json_reply_to_plan_text(json_text: str) -> str:
    """Turn a JSON-form reply into the paper's text form, so one reply parser reads both.

    Only the shape is checked here (an object with a ``plan`` list of lists of strings);
    whether the names exist is the reply parser's job, as it is for text replies.
    """
    try:
        data = json.loads(json_text)
    except json.JSONDecodeError as error:
        raise StalmError(
            f"structured reply is not valid JSON ({error}): {json_text[:80]!r}"
        ) from error
    if not isinstance(data, dict):
        raise StalmError("structured reply must be a JSON object with 'challenges' and 'plan'")
    challenges = data.get("challenges")
    if isinstance(challenges, list):
        challenges = "\n".join(str(line) for line in challenges)
    if challenges is not None and not isinstance(challenges, str):
        raise StalmError("structured reply field 'challenges' must be a string")
    plan = data.get("plan")
    if not isinstance(plan, list):
        raise StalmError("structured reply field 'plan' must be a list of steps")
    steps = []
    for index, step in enumerate(plan):
        if not isinstance(step, list) or not all(isinstance(arg, str) for arg in step):
            raise StalmError(
                f"structured reply field 'plan[{index}]' must be a list of strings, got {step!r}"
            )
        steps.append("(" + ", ".join(repr(arg) for arg in step) + ")")
    plan_text = f"{PLAN_HEADER}\nplan = [{', '.join(steps)}]\n"
    if challenges is None:  # the no-challenges form (Table 4's ablation, SayCan)
        return plan_text
    return f"{CHALLENGES_HEADER}\n{challenges.strip()}\n\n{plan_text}"


__all__ = [
    "CHALLENGES_HEADER",
    "CONSTRAINT_NAME",
    "PLAN_HEADER",
    "ConstraintLimits",
    "OutputConstraint",
    "build_constraint",
    "build_gbnf",
    "build_json_schema",
    "json_reply_to_plan_text",
]
