"""The prompt reproduces the paper's Figure 13 and applies the Table 4 ablations.

Golden file: ``golden/p5_figure13_prompt.txt`` is the paper's Figure 13 transcribed as it stands
in /work/shared/paper/prime-the-search.md, from "**System prompt**" to the closing request,
including the "**System prompt**"/"**User prompt**" headings (``Prompt.as_transcript`` adds
them). Where the transcription is ambiguous about whitespace we keep it as transcribed rather
than guess: the reply template's "## Plan for unachieved goals ## plan = [...]" stays on one
line, sections are separated by exactly one blank line, and no line has trailing spaces.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.prompt import Prompt, PromptOptions, build_prompt
from stalm.predicates.literals import GroundLiteral

from .scenarios import FIGURE13_GOAL, FIGURE13_INIT, FIGURE13_VOCABULARY

GOLDEN = Path(__file__).parent / "golden" / "p5_figure13_prompt.txt"


def figure13(options: PromptOptions = PromptOptions()) -> Prompt:  # noqa: B008
    return build_prompt(FIGURE13_VOCABULARY, FIGURE13_INIT, FIGURE13_GOAL, options)


def test_figure13_prompt_matches_the_paper_exactly() -> None:
    assert figure13().as_transcript() == GOLDEN.read_text(encoding="utf-8")


def test_messages_split_where_the_paper_splits_them() -> None:
    prompt = figure13()
    assert prompt.system.startswith("You are an expert proficient in PDDL")
    assert prompt.system.endswith("plan = [('action_type', 'args_1', 'args_2',...), ]")
    assert prompt.user.startswith("### Domain ###\n(define (domain shop)\n")
    assert prompt.user.endswith("\n\nGenerate a plan to achieve the goals from init.")


def test_objects_init_and_goal_formats() -> None:
    vocabulary = Vocabulary(movables=("coke",), regions=("counter1",), doors=("door",))
    init = [GroundLiteral("HandAvailable"), GroundLiteral("IsClosed", ("door",))]
    goal = [GroundLiteral("AtPosition", ("coke", "on", "counter1"))]
    user = build_prompt(vocabulary, init, goal).user
    assert "(:objects coke - movable_object door - openable counter1 - region )" in user
    assert "(:init\n[('HandAvailable', ''), ('IsClosed', 'door')] )" in user
    assert "(:goal (and (AtPosition coke on counter1) ) )" in user


def test_init_order_is_kept() -> None:
    reversed_init = tuple(reversed(FIGURE13_INIT))
    user = build_prompt(FIGURE13_VOCABULARY, reversed_init, FIGURE13_GOAL).user
    assert "[('PlaceOccludedBy', 'dr_pepper', 'behind_of', 'beef_grill', 'beef_grill'), " in user
    assert user.index("'HandAvailable'") > user.index("'PickOccludedBy'")


def test_without_occlusion_predicates_nothing_mentions_occlusion() -> None:
    prompt = figure13(PromptOptions(occlusion_predicates=False))
    for word in ("OccludedBy", "Unsafe", ":derived", "occluder"):
        assert word not in prompt.user
    assert "(IsClosed ?door) ; True if the door is closed )\n" in prompt.user
    assert ":precondition (and (HandAvailable ) )\n" in prompt.user
    assert ":precondition (and (RobotHolding ?subject) )\n" in prompt.user
    assert "('AtPosition', 'coke', 'on', 'counter2')" in prompt.user
    # Only the occlusion parts go: the rest is the full prompt's text.
    assert prompt.system == figure13().system


def test_without_challenges_the_template_asks_only_for_the_plan() -> None:
    prompt = figure13(PromptOptions(ask_challenges=False))
    assert "Challenges" not in prompt.system
    assert prompt.system == (
        "You are an expert proficient in PDDL and planning actions for a problem. Your response "
        "should follow this template:\n"
        "## Plan for unachieved goals ## plan = [('action_type', 'args_1', 'args_2',...), ]"
    )
    assert prompt.user == figure13().user


def test_options_are_frozen() -> None:
    options = PromptOptions()
    with pytest.raises(AttributeError):
        options.ask_challenges = False  # type: ignore[misc]


@pytest.mark.parametrize(
    ("literal", "message"),
    [
        (GroundLiteral("RobotAt", ("counter1",)), "unknown predicate 'RobotAt'"),
        (GroundLiteral("AtPosition", ("wine", "on", "counter1")), "unknown name 'wine'"),
    ],
)
def test_unknown_predicates_and_names_are_user_errors(literal: GroundLiteral, message: str) -> None:
    with pytest.raises(StalmError, match=message):
        build_prompt(FIGURE13_VOCABULARY, [literal], FIGURE13_GOAL)
    with pytest.raises(StalmError, match=message):
        build_prompt(FIGURE13_VOCABULARY, FIGURE13_INIT, [literal])
