"""Relevance-limited predicates (``predicates.relevant_only``, beyond the paper).

Occlusion literals are computed for the goal's objects and, recursively, what occludes them;
placements only at the goal. For the objects covered they are the full computation's
literals (the samples are seeded by names, so both draw the same motions); the objects they
covered are stated (``OcclusionComputed``), shown to a model as a prompt section, and left out
of every PDDL.
"""

from __future__ import annotations

import pytest

from stalm.domain.vocabulary import Vocabulary
from stalm.llm.pddl import problem_pddl
from stalm.llm.problem_prompt import goal_literals, problem_prompt
from stalm.llm.prompt import PromptOptions
from stalm.predicates.cache import PredicateCache
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.literals import SCOPE_PREDICATE, GroundLiteral
from stalm.predicates.samples import PredicateSettings
from stalm.world.problem import Problem
from tests.cli_runner import run_cli


@pytest.fixture(scope="module")
def p2_both(domain_factory) -> tuple[Problem, PredicateCache, PredicateCache]:
    domain = domain_factory("P2")
    problem = domain.problem
    full, relevant = (
        PredicateEngine(
            problem, domain.sim, domain.base_planner, PredicateSettings(relevant_only=only)
        ).compute(problem.initial_state)
        for only in (False, True)
    )
    return problem, full, relevant


def _about(literals: frozenset[GroundLiteral], name: str, obj: str) -> set[GroundLiteral]:
    return {lit for lit in literals if lit.name == name and lit.args[0] == obj}


def test_the_goal_objects_and_what_blocks_them_are_covered(p2_both) -> None:
    problem, full, relevant = p2_both
    assert relevant.relevant is not None
    assert {"salter", "bottle1"} <= relevant.relevant  # the goal's object and its reference
    salter_blockers = {lit.args[1] for lit in _about(full.literals, "PickOccludedBy", "salter")}
    doors = {door.name for door in problem.spec.doors}  # a door opens: it is not followed
    assert "kitchen_door" in salter_blockers and salter_blockers - doors  # P2's salter is boxed in
    assert salter_blockers - doors <= relevant.relevant  # followed recursively
    stated = {lit.args[0] for lit in relevant.literals if lit.name == SCOPE_PREDICATE}
    assert stated == relevant.relevant
    assert not any(lit.name == SCOPE_PREDICATE for lit in full.literals)


def test_covered_objects_have_the_full_computations_literals(p2_both) -> None:
    problem, full, relevant = p2_both
    assert relevant.relevant is not None
    for obj in relevant.relevant:
        assert _about(relevant.literals, "PickOccludedBy", obj) == _about(
            full.literals, "PickOccludedBy", obj
        ), obj
    for goal in problem.goal:
        relation = (goal.obj, goal.direction, goal.ref)
        assert {
            lit
            for lit in relevant.literals
            if lit.name == "PlaceOccludedBy" and lit.args[:3] == relation
        } == {
            lit
            for lit in full.literals
            if lit.name == "PlaceOccludedBy" and lit.args[:3] == relation
        }
    occluded = {lit.args[0] for lit in relevant.literals if lit.name == "PickOccludedBy"}
    assert occluded <= relevant.relevant  # nothing about the objects left out
    symbolic = {lit for lit in full.literals if lit.name in ("AtPosition", "HandAvailable")}
    assert symbolic <= relevant.literals  # what needs no motion is always there


def test_the_prompt_names_what_was_covered_and_the_pddl_ignores_it(p2_both) -> None:
    problem, full, relevant = p2_both
    literals = sorted(relevant.literals)
    prompt = problem_prompt(problem, literals, PromptOptions())
    assert "### Occlusion computed for ###" in prompt.user
    assert SCOPE_PREDICATE not in prompt.user.split("### Occlusion computed for ###")[0]
    assert "salter" in prompt.user.split("### Occlusion computed for ###")[1]
    paper = problem_prompt(problem, sorted(full.literals), PromptOptions())
    assert "Occlusion computed" not in paper.user  # the paper's prompt, unchanged
    vocabulary = Vocabulary.from_problem(problem)
    text = problem_pddl(vocabulary, literals, goal_literals(problem), "p2")
    assert SCOPE_PREDICATE not in text and "PickOccludedBy salter" in text


def test_stalm_predicates_prints_what_it_covered(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "predicates", "P2", "--relevant-only") == 0
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if line.startswith("occlusion computed for:"))
    assert "salter" in line and "bottle1" in line
    assert SCOPE_PREDICATE not in out
