"""Property tests: no text makes the parser raise, and whatever it returns is well-formed.

Random text, random mutations (insert, delete, replace, cut) of the paper's real replies, and
plans rendered in random styles. Whatever the input, every planned action is an action of the
problem, the plan is the valid prefix of the steps, and the result serialises to JSON.
"""

from __future__ import annotations

import json
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from stalm.domain.actions import DiscreteAction
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.reply_parser import ParsedReply, parse_reply

from .scenarios import P1, P2, P3, P4, P5, P6

DATA = Path(__file__).parent / "data"
REPLIES = [
    (path.read_text(encoding="utf-8"), vocabulary)
    for path, vocabulary in zip(
        sorted(DATA.glob("figure*_reply.txt")), (P1, P2, P3, P4, P5, P6), strict=True
    )
]
FUZZ = settings(max_examples=150, deadline=None)

# Characters that matter to the scanner, mixed with ordinary text.
SYNTAX = st.sampled_from([*"()[]'\",#`\\\n =_", "plan = [", "```", "# ]", "('pick', "])
TEXT = st.lists(st.one_of(SYNTAX, st.text(max_size=8)), max_size=60).map("".join)


def check_well_formed(parsed: ParsedReply, vocabulary: Vocabulary) -> None:
    space = set(vocabulary.all_discrete_actions())
    assert all(action in space for action in parsed.plan)
    prefix: list[DiscreteAction] = []
    for step in parsed.steps:
        assert (step.action is None) != (step.error is None)
        if step.action is None:
            break
        prefix.append(step.action)
    if parsed.plan:
        assert list(parsed.plan) == prefix
    assert [error.index for error in parsed.errors] == [
        step.index for step in parsed.steps if step.error is not None
    ]
    if not parsed.plan:
        assert parsed.reason is not None
    json.dumps(parsed.to_json())


@FUZZ
@given(text=st.text(max_size=300))
def test_random_unicode_text_never_raises(text: str) -> None:
    check_well_formed(parse_reply(text, P5), P5)


@FUZZ
@given(text=TEXT)
def test_random_syntax_soup_never_raises(text: str) -> None:
    check_well_formed(parse_reply(text, P5), P5)
    check_well_formed(parse_reply("plan = [" + text, P5), P5)


@st.composite
def mutated_reply(draw: st.DrawFn) -> tuple[str, Vocabulary]:
    text, vocabulary = draw(st.sampled_from(REPLIES))
    for _ in range(draw(st.integers(1, 6))):
        position = draw(st.integers(0, len(text)))
        operation = draw(st.sampled_from(["insert", "delete", "replace", "cut"]))
        piece = draw(st.one_of(SYNTAX, st.text(max_size=4)))
        end = min(len(text), position + draw(st.integers(0, 12)))
        if operation == "insert":
            text = text[:position] + piece + text[position:]
        elif operation == "delete":
            text = text[:position] + text[end:]
        elif operation == "replace":
            text = text[:position] + piece + text[end:]
        else:
            text = text[:position]
    return text, vocabulary


@FUZZ
@given(case=mutated_reply())
def test_mutated_paper_replies_never_raise(case: tuple[str, Vocabulary]) -> None:
    text, vocabulary = case
    check_well_formed(parse_reply(text, vocabulary), vocabulary)


@st.composite
def rendered_plan(draw: st.DrawFn) -> tuple[str, tuple[DiscreteAction, ...]]:
    actions = P2.all_discrete_actions()
    plan = tuple(draw(st.lists(st.sampled_from(actions), min_size=1, max_size=8)))
    quote = draw(st.sampled_from(["'", '"']))
    separator = draw(st.sampled_from([", ", ",\n", ", # next\n", " ,  "]))
    steps = [
        "(" + ", ".join(f"{quote}{item}{quote}" for item in action.as_tuple()) + ")"
        for action in plan
    ]
    body = separator.join(steps)
    ending = draw(st.sampled_from(["]", "\n]", " # done ]", ",\n]"]))
    prose = draw(st.sampled_from(["", "## Plan ##\n", "Some thoughts (a, b).\n"]))
    fenced = draw(st.booleans())
    text = f"{prose}plan = [{body}{ending}"
    return (f"```python\n{text}\n```" if fenced else text), plan


@FUZZ
@given(case=rendered_plan())
def test_rendered_plans_parse_back_exactly(case: tuple[str, tuple[DiscreteAction, ...]]) -> None:
    text, plan = case
    parsed = parse_reply(text, P2)
    assert parsed.plan == plan
    assert parsed.reason is None
