"""The strict PDDL is accepted by real tools and means what the prompt's abstraction says.

Two external tools from PyPI (in the ``dev`` extra): the ``pddl`` parser, and Fast Downward's
translator (``python -m fast_downward.translate DOMAIN PROBLEM --sas-file OUT``), which grounds
the task; :mod:`tests.llm.sas` then evaluates the grounded task (applicable operators, shortest
plans) to check the semantics, not just the syntax.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from pddl import parse_domain, parse_problem

from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.pddl import domain_pddl, problem_pddl, requirements
from stalm.llm.prompt import PromptOptions
from stalm.predicates.literals import GroundLiteral

from .sas import SasTask, translate
from .scenarios import FIGURE13_GOAL, FIGURE13_INIT, FIGURE13_VOCABULARY

NO_OCCLUSION = PromptOptions(occlusion_predicates=False)


def lit(name: str, *args: str) -> GroundLiteral:
    return GroundLiteral(name, args)


def ground(
    tmp_path: Path,
    vocabulary: Vocabulary,
    init: tuple[GroundLiteral, ...] | list[GroundLiteral],
    goal: tuple[GroundLiteral, ...] | list[GroundLiteral],
    options: PromptOptions = PromptOptions(),  # noqa: B008
) -> SasTask:
    return translate(
        domain_pddl(options), problem_pddl(vocabulary, init, goal, "test", options), tmp_path
    )


def applicable_names(task: SasTask) -> set[tuple[str, ...]]:
    return {operator.name for operator in task.applicable(task.init)}


@pytest.mark.parametrize("options", [PromptOptions(), NO_OCCLUSION])
def test_pddl_parser_accepts_domain_and_problem(tmp_path: Path, options: PromptOptions) -> None:
    (tmp_path / "domain.pddl").write_text(domain_pddl(options))
    (tmp_path / "problem.pddl").write_text(
        problem_pddl(FIGURE13_VOCABULARY, FIGURE13_INIT, FIGURE13_GOAL, "p5 fig13", options)
    )
    domain = parse_domain(tmp_path / "domain.pddl")
    problem = parse_problem(tmp_path / "problem.pddl")
    assert {action.name for action in domain.actions} == {"pick", "place", "open"}
    assert len(domain.derived_predicates) == (2 if options.occlusion_predicates else 0)
    assert str(problem.name) == "p5-fig13"
    expected = len(FIGURE13_INIT) if options.occlusion_predicates else 10
    assert len(problem.init) == expected


def test_requirements_follow_the_ablation() -> None:
    assert ":derived-predicates" in requirements(PromptOptions())
    assert ":derived-predicates" not in requirements(NO_OCCLUSION)
    assert "(:requirements :strips :typing" in domain_pddl()


def test_ground_actions_are_exactly_the_action_space(tmp_path: Path) -> None:
    """Place's ADL precondition ties 'on' to regions and relative directions to movables."""
    vocabulary = Vocabulary(movables=("a", "b", "c"), regions=("r1", "r2"), doors=("door",))
    # The translator drops operators irrelevant to the goal: the door blocks 'a' to keep OPEN.
    init = [lit("HandAvailable"), lit("IsClosed", "door"), lit("PickOccludedBy", "a", "door")]
    task = ground(tmp_path, vocabulary, init, [lit("AtPosition", "a", "on", "r2")])
    expected = {action.as_tuple() for action in vocabulary.all_discrete_actions()}
    assert task.operator_names() == expected
    assert len(task.operators) == len(expected) == 3 + (3 * 2 + 3 * 2 * 4) + 1


def test_figure13_grounds_to_every_action_but_opening_the_open_door(tmp_path: Path) -> None:
    task = ground(tmp_path, FIGURE13_VOCABULARY, FIGURE13_INIT, FIGURE13_GOAL)
    expected = {a.as_tuple() for a in FIGURE13_VOCABULARY.all_discrete_actions()}
    # Figure 13's init has no IsClosed literal: the door is open, so OPEN is unreachable.
    assert task.operator_names() == expected - {("open", "kitchen_door")}


def test_occluded_pick_is_not_applicable(tmp_path: Path) -> None:
    task = ground(tmp_path, FIGURE13_VOCABULARY, FIGURE13_INIT, FIGURE13_GOAL)
    picks = {name for name in applicable_names(task) if name[0] == "pick"}
    movables = set(FIGURE13_VOCABULARY.movables)
    assert picks == {("pick", obj) for obj in movables - {"coke"}}


def test_without_occlusion_the_occluded_pick_is_allowed(tmp_path: Path) -> None:
    task = ground(tmp_path, FIGURE13_VOCABULARY, FIGURE13_INIT, FIGURE13_GOAL, NO_OCCLUSION)
    assert ("pick", "coke") in applicable_names(task)


def test_occluded_place_is_not_applicable(tmp_path: Path) -> None:
    init = [lit("RobotHolding", "sprite")] + [
        literal for literal in FIGURE13_INIT if literal.name != "HandAvailable"
    ]
    task = ground(tmp_path, FIGURE13_VOCABULARY, init, FIGURE13_GOAL)
    names = applicable_names(task)
    assert ("place", "sprite", "on", "counter1") in names
    assert ("place", "sprite", "on", "counter2") not in names  # occluded by beef_grill
    assert ("place", "sprite", "right_of", "coke") not in names
    assert ("place", "sprite", "front_of", "coke") in names
    assert not any(name[0] == "pick" for name in names)  # the hand is full


def test_occluders_must_be_moved_first(tmp_path: Path) -> None:
    """P2 in miniature: the salter stands behind two bottles that block its pick."""
    vocabulary = Vocabulary(
        movables=("salter", "bottle2", "bottle3"), regions=("counter2", "table2"), doors=()
    )
    init = [
        lit("HandAvailable"),
        *(lit("AtPosition", obj, "on", "counter2") for obj in vocabulary.movables),
        lit("PickOccludedBy", "salter", "bottle2"),
        lit("PickOccludedBy", "salter", "bottle3"),
    ]
    task = ground(tmp_path, vocabulary, init, [lit("AtPosition", "salter", "on", "table2")])
    plan = task.shortest_plan()
    assert plan is not None
    assert len(plan) == 6
    assert {step[:2] for step in plan[:4:2]} == {("pick", "bottle2"), ("pick", "bottle3")}
    assert plan[4:] == [("pick", "salter"), ("place", "salter", "on", "table2")]


def test_a_closed_door_must_be_opened_first(tmp_path: Path) -> None:
    vocabulary = Vocabulary(movables=("coke",), regions=("table1", "counter1"), doors=("door",))
    init = [
        lit("HandAvailable"),
        lit("IsClosed", "door"),
        lit("AtPosition", "coke", "on", "table1"),
        lit("PickOccludedBy", "coke", "door"),
    ]
    task = ground(tmp_path, vocabulary, init, [lit("AtPosition", "coke", "on", "counter1")])
    assert task.shortest_plan() == [
        ("open", "door"),
        ("pick", "coke"),
        ("place", "coke", "on", "counter1"),
    ]


@pytest.mark.parametrize(
    ("fact", "holds_after_pick"),
    [
        (("a", "on", "r"), False),
        (("a", "left_of", "b"), False),
        (("b", "right_of", "a"), True),  # the abstraction only forgets the picked object's
        (("b", "on", "r"), True),
    ],
)
def test_pick_forgets_every_position_of_the_picked_object(
    tmp_path: Path, fact: tuple[str, str, str], holds_after_pick: bool
) -> None:
    vocabulary = Vocabulary(movables=("a", "b"), regions=("r",), doors=())
    init = [
        lit("HandAvailable"),
        lit("AtPosition", "a", "on", "r"),
        lit("AtPosition", "a", "left_of", "b"),
        lit("AtPosition", "b", "on", "r"),
        lit("AtPosition", "b", "right_of", "a"),
    ]
    task = ground(tmp_path, vocabulary, init, [lit("AtPosition", *fact)])
    assert task.is_goal(task.init)
    (pick,) = [op for op in task.operators if op.name == ("pick", "a")]
    assert task.is_goal(task.apply(task.init, pick)) is holds_after_pick


def test_mutually_occluding_objects_cannot_be_picked(tmp_path: Path) -> None:
    vocabulary = Vocabulary(movables=("a", "b"), regions=("r", "s"), doors=())
    init = [
        lit("HandAvailable"),
        lit("PickOccludedBy", "a", "b"),
        lit("PickOccludedBy", "b", "a"),
    ]
    task = ground(tmp_path, vocabulary, init, [lit("AtPosition", "a", "on", "s")])
    assert not any(name[0] == "pick" for name in applicable_names(task))
    assert task.shortest_plan() is None


@pytest.mark.parametrize(
    ("vocabulary", "literal", "message"),
    [
        (Vocabulary(("a b",), ("r",), ()), None, "not a valid PDDL name"),
        (Vocabulary(("on",), ("r",), ()), None, "clashes with 'on'"),
        (Vocabulary(("Coke", "coke"), ("r",), ()), None, "PDDL ignores case"),
        (Vocabulary(("a",), ("r",), ()), lit("RobotAt", "r"), "unknown predicate"),
        (Vocabulary(("a",), ("r",), ()), lit("AtPosition", "a", "r"), "takes 3 argument"),
        (Vocabulary(("a",), ("r",), ()), lit("RobotHolding", "z"), "unknown name 'z'"),
    ],
)
def test_problems_pddl_cannot_express_are_user_errors(
    vocabulary: Vocabulary, literal: GroundLiteral | None, message: str
) -> None:
    init = [literal] if literal is not None else []
    with pytest.raises(StalmError, match=message):
        problem_pddl(vocabulary, init, [], "x")


def test_problem_name_is_made_a_pddl_name() -> None:
    text = problem_pddl(Vocabulary(("a",), ("r",), ()), [], [], "5 trials/P5")
    assert text.startswith("(define (problem problem-5-trials-P5)\n")
