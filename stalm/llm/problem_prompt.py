"""The prompt for a problem in a given state: predicates as the init, the goal as AtPosition.

Literal order follows Figure 13: the hand, doors, positions (each object's region, then its
relations to the objects beside it), then pick occlusions and place occlusions; within a group
the order is the problem file's object order, so prompts are stable and diffable.
"""

from __future__ import annotations

from collections.abc import Iterable

from stalm.domain.vocabulary import Vocabulary
from stalm.llm.prompt import Prompt, PromptOptions, build_prompt
from stalm.predicates.literals import GroundLiteral
from stalm.world.problem import Problem

_GROUP = {
    "HandAvailable": 0,
    "RobotHolding": 0,
    "IsClosed": 1,
    "AtPosition": 2,
    "PickOccludedBy": 3,
    "PlaceOccludedBy": 4,
}


def ordered_literals(problem: Problem, literals: Iterable[GroundLiteral]) -> list[GroundLiteral]:
    """Literals in prompt order (see the module docstring)."""
    vocabulary = Vocabulary.from_problem(problem)
    rank = {name: index for index, name in enumerate(vocabulary.all_names)}
    directions = {"on": 0, "left_of": 1, "right_of": 2, "front_of": 3, "behind_of": 4}

    def key(literal: GroundLiteral) -> tuple[object, ...]:
        args = literal.args
        names = tuple(rank.get(a, len(rank)) for a in args if a not in directions)
        dirs = tuple(directions[a] for a in args if a in directions)
        if literal.name == "AtPosition":
            # the object's region first, then its relations
            return (_GROUP[literal.name], names[0], dirs[0] != 0, dirs, names[1:])
        return (_GROUP.get(literal.name, 9), names, dirs)

    return sorted(literals, key=key)


def goal_literals(problem: Problem) -> list[GroundLiteral]:
    return [GroundLiteral("AtPosition", (g.obj, g.direction, g.ref)) for g in problem.goal]


def problem_prompt(
    problem: Problem, literals: Iterable[GroundLiteral], options: PromptOptions | None = None
) -> Prompt:
    """The paper's prompt for ``problem`` in the state whose predicates are ``literals``."""
    return build_prompt(
        Vocabulary.from_problem(problem),
        ordered_literals(problem, literals),
        goal_literals(problem),
        options or PromptOptions(),
    )
