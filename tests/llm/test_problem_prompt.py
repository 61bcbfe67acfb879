"""The prompt of every problem: Figure 13's domain, the computed literals as init, the goal."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from stalm.llm.problem_prompt import goal_literals, ordered_literals, problem_prompt
from stalm.llm.prompt import PromptOptions

GOLDEN = Path(__file__).parent / "golden" / "p5_figure13_prompt.txt"


def _figure13_domain_lines() -> list[str]:
    text = GOLDEN.read_text()
    domain = text[text.index("### Domain ###") : text.index("### Problem ###")]
    return [line for line in domain.splitlines() if line.strip()]


@pytest.mark.parametrize("name", ["P1", "P2", "P3", "P4", "P5", "P6"])
def test_prompt_of_each_problem(problems, initial_literals, name) -> None:
    problem = problems[name]
    literals = initial_literals(name)
    prompt = problem_prompt(problem, literals)
    for line in _figure13_domain_lines():
        assert line in prompt.user, line
    init_text = prompt.user[
        prompt.user.index("(:init") + len("(:init") : prompt.user.index("(:goal")
    ]
    listed = ast.literal_eval(init_text.strip().removesuffix(")").strip())
    assert listed == [lit.as_tuple() for lit in ordered_literals(problem, literals)]
    assert sorted(listed) == sorted(lit.as_tuple() for lit in literals)
    for goal in goal_literals(problem):
        assert f"(AtPosition {' '.join(goal.args)})" in prompt.user
    assert "Possible Challenges" in prompt.system
    objects = re.search(r"\(:objects (.*?)\)", prompt.user)
    assert objects is not None
    for obj in problem.spec.objects:
        assert f"{obj.name} - movable_object" in objects.group(1)


def test_prompt_ablations_drop_what_they_say(problems, initial_literals) -> None:
    problem = problems["P2"]
    plain = [lit for lit in initial_literals("P2") if "Occluded" not in lit.name]
    prompt = problem_prompt(
        problem, plain, PromptOptions(occlusion_predicates=False, ask_challenges=False)
    )
    assert "PickOccludedBy" not in prompt.user and "UnsafePick" not in prompt.user
    assert "Possible Challenges" not in prompt.system
