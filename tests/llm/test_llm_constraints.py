"""Output constraints: the grammar and schema admit the reply template with the problem's own
names only, and a JSON reply reads back as the text form the reply parser understands."""

from __future__ import annotations

import json
import re

import jsonschema
import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.constraints import (
    CHALLENGES_HEADER,
    PLAN_HEADER,
    ConstraintLimits,
    build_constraint,
    build_gbnf,
    build_json_schema,
    json_reply_to_plan_text,
)
from stalm.llm.reply_parser import parse_reply

GOOD_REPLY = {
    "challenges": "1. coke is occluded by kitchen_door.",
    "plan": [
        ["open", "kitchen_door"],
        ["pick", "coke"],
        ["place", "coke", "on", "counter1"],
        ["pick", "sprite"],
        ["place", "sprite", "left_of", "coke"],
    ],
}


def validator(vocabulary: Vocabulary) -> jsonschema.Draft202012Validator:
    schema = build_json_schema(vocabulary)
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_grammar_names_every_entity_and_the_headers(p5_vocabulary: Vocabulary) -> None:
    grammar = build_gbnf(p5_vocabulary)
    for name in p5_vocabulary.all_names:
        assert f"\"'{name}'\"" in grammar
    for direction in ("left_of", "right_of", "front_of", "behind_of"):
        assert f"\"'{direction}'\"" in grammar
    assert CHALLENGES_HEADER in grammar and PLAN_HEADER in grammar
    assert "('pick', " in grammar and "('open', " in grammar
    # Every rule referenced is defined (llama.cpp would reject the grammar otherwise).
    defined = set(re.findall(r"^([a-z0-9-]+) ::=", grammar, re.MULTILINE))
    bodies = re.sub(r'"(?:[^"\\]|\\.)*"|\[[^\]]*\]', "", grammar)
    used = set(re.findall(r"(?<![\w-])([a-z][a-z0-9-]*)(?![\w-])", bodies.replace("::=", " ")))
    assert used <= defined


def test_grammar_is_bounded(p5_vocabulary: Vocabulary) -> None:
    grammar = build_gbnf(
        p5_vocabulary, ConstraintLimits(max_challenge_lines=3, max_line_chars=80, max_steps=12)
    )
    assert "challenge-line{1,3}" in grammar
    assert "text-char{1,80}" in grammar
    assert "(step-sep step){0,11}" in grammar
    assert "*" not in grammar and "+" not in grammar  # no unbounded repetition anywhere


def test_grammar_never_places_an_object_relative_to_itself(p5_vocabulary: Vocabulary) -> None:
    grammar = build_gbnf(p5_vocabulary)
    rule = next(line for line in grammar.splitlines() if line.startswith("others-0 ::="))
    assert "'coke'" not in rule and "'sprite'" in rule


def test_grammar_leaves_out_what_the_problem_lacks() -> None:
    grammar = build_gbnf(Vocabulary(movables=("cup",), regions=("table",), doors=()))
    assert "open" not in grammar and "rel-dir" not in grammar
    assert "step ::= pick | place" in grammar


def test_problems_without_movables_or_with_odd_names_are_user_errors() -> None:
    with pytest.raises(StalmError, match="without movable"):
        build_constraint(Vocabulary(movables=(), regions=("table",), doors=()))
    with pytest.raises(StalmError, match="quote"):
        build_constraint(Vocabulary(movables=("o'brien",), regions=(), doors=()))


def test_limits_are_checked() -> None:
    with pytest.raises(StalmError, match="max_steps"):
        ConstraintLimits(max_steps=0)
    with pytest.raises(StalmError, match="max_challenge_lines"):
        ConstraintLimits(max_challenge_lines=10)


def test_schema_accepts_a_good_reply(p5_vocabulary: Vocabulary) -> None:
    validator(p5_vocabulary).validate(GOOD_REPLY)


@pytest.mark.parametrize(
    "bad_step",
    [
        ["pick", "wine"],  # not in the problem
        ["pick", "counter1"],  # a region is not movable
        ["open", "coke"],  # only doors open
        ["place", "coke", "on", "sprite"],  # 'on' takes a region
        ["place", "coke", "left_of", "counter1"],  # relative places take a movable
        ["place", "coke", "left_of", "coke"],  # never relative to itself
        ["place", "coke", "above", "sprite"],  # unknown direction
        ["place", "coke", "on"],  # arity
        ["pick", "coke", "extra"],
        ["fly", "coke"],
    ],
)
def test_schema_rejects_bad_steps(p5_vocabulary: Vocabulary, bad_step: list[str]) -> None:
    reply = {"challenges": "", "plan": [["pick", "coke"], bad_step]}
    assert not validator(p5_vocabulary).is_valid(reply)


@pytest.mark.parametrize(
    "bad_reply",
    [
        {"challenges": "x"},
        {"plan": [["pick", "coke"]]},
        {"challenges": "x", "plan": []},
        {"challenges": "x", "plan": [["pick", "coke"]] * 21},
        {"challenges": "x" * 2000, "plan": [["pick", "coke"]]},
        {"challenges": "x", "plan": [["pick", "coke"]], "notes": "extra"},
    ],
)
def test_schema_rejects_bad_shapes(p5_vocabulary: Vocabulary, bad_reply: dict[str, object]) -> None:
    assert not validator(p5_vocabulary).is_valid(bad_reply)


def test_json_reply_reads_back_as_the_text_form(p5_vocabulary: Vocabulary) -> None:
    text = json_reply_to_plan_text(json.dumps(GOOD_REPLY))
    assert text.startswith(CHALLENGES_HEADER + "\n1. coke is occluded")
    assert f"\n\n{PLAN_HEADER}\nplan = [('open', 'kitchen_door'), ('pick', 'coke'), " in text
    parsed = parse_reply(text, p5_vocabulary)
    assert parsed.reason is None
    assert parsed.plan == (
        Open("kitchen_door"),
        Pick("coke"),
        Place("coke", "on", "counter1"),
        Pick("sprite"),
        Place("sprite", "left_of", "coke"),
    )


@pytest.mark.parametrize(
    ("json_text", "message"),
    [
        ('{"challenges": "cut', "not valid JSON"),
        ("[1, 2]", "JSON object"),
        ('{"challenges": "x", "plan": "pick coke"}', "'plan' must be a list"),
        ('{"challenges": "x", "plan": [["pick", 3]]}', "plan\\[0\\]"),
        ('{"challenges": 5, "plan": []}', "'challenges' must be a string"),
    ],
)
def test_malformed_json_replies_are_user_errors(json_text: str, message: str) -> None:
    with pytest.raises(StalmError, match=message):
        json_reply_to_plan_text(json_text)


def test_constraint_fingerprint_is_stable_and_specific(p5_vocabulary: Vocabulary) -> None:
    first = build_constraint(p5_vocabulary)
    assert first == build_constraint(p5_vocabulary)
    assert first.fingerprint == build_constraint(p5_vocabulary).fingerprint
    other = build_constraint(Vocabulary(("coke",), ("counter1",), ()))
    assert other.fingerprint != first.fingerprint
    assert first.json_schema() == build_json_schema(p5_vocabulary)


def _rules_are_defined(grammar: str) -> bool:
    defined = set(re.findall(r"^([a-z0-9-]+) ::=", grammar, re.MULTILINE))
    bodies = re.sub(r'"(?:[^"\\]|\\.)*"|\[[^\]]*\]', "", grammar)
    used = set(re.findall(r"(?<![\w-])([a-z][a-z0-9-]*)(?![\w-])", bodies.replace("::=", " ")))
    return used <= defined


def test_without_challenges_the_grammar_starts_with_the_plan(p5_vocabulary: Vocabulary) -> None:
    grammar = build_gbnf(p5_vocabulary, challenges=False)
    assert CHALLENGES_HEADER not in grammar and "challenge" not in grammar
    root = next(line for line in grammar.splitlines() if line.startswith("root ::="))
    assert root.startswith("root ::= plan-head ")
    assert f'plan-head ::= "{PLAN_HEADER}\\n"' in grammar
    assert _rules_are_defined(grammar)
    # the plan part is the same as with challenges
    with_challenges = build_gbnf(p5_vocabulary)
    assert grammar.split("step-sep ::=")[1] == with_challenges.split("step-sep ::=")[1]


def test_without_challenges_the_schema_asks_for_the_plan_alone(p5_vocabulary: Vocabulary) -> None:
    schema = build_json_schema(p5_vocabulary, challenges=False)
    jsonschema.Draft202012Validator.check_schema(schema)
    plan_only = jsonschema.Draft202012Validator(schema)
    assert schema["required"] == ["plan"] and "challenges" not in schema["properties"]
    assert plan_only.is_valid({"plan": GOOD_REPLY["plan"]})
    assert not plan_only.is_valid(GOOD_REPLY)  # challenges are not admitted either
    text = json_reply_to_plan_text(json.dumps({"plan": GOOD_REPLY["plan"]}))
    assert text.startswith(PLAN_HEADER + "\nplan = [('open', 'kitchen_door'), ")
    assert CHALLENGES_HEADER not in text
    assert len(parse_reply(text, p5_vocabulary).plan) == 5
    constraint = build_constraint(p5_vocabulary, challenges=False)
    assert constraint.json_schema() == schema
    assert constraint.fingerprint != build_constraint(p5_vocabulary).fingerprint
