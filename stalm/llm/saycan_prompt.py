"""The EP-SayCan baseline's prompt (§4.2): the task, the action vocabulary and the history.

SayCan (Ahn et al., 2022) prompts with a task instruction and the actions executed so far and
nothing about the state; the paper keeps that setting on purpose, to measure what STaLM's
predicates buy. So this prompt names the goal, every object, region and door (the model must be
able to name them), the three operators, and the executed actions in order -- and no
predicates: no hand state, no positions, no occlusions. Replies use STaLM's template
(``plan = [('pick', 'x'), ...]``) so :func:`~stalm.llm.reply_parser.parse_reply` reads them and
the embedded model's output constraint applies unchanged. The wording lives in
``templates/saycan_system.txt`` and ``templates/saycan_user.txt``.
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib import resources
from string import Template

from stalm.domain.actions import DiscreteAction
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.prompt import Prompt
from stalm.world.problem import Problem

NO_HISTORY = "(none yet)"


def _fill(name: str, **values: str) -> str:
    text = resources.files("stalm.llm").joinpath("templates", f"{name}.txt").read_text("utf-8")
    return Template(text.removesuffix("\n")).substitute(values)


def task_instruction(problem: Problem) -> str:
    """The goal in words with the problem's own names, e.g. ``Put salter on table2 and ...``.

    Relations keep their action spelling (``right_of``) so the model sees the word it must
    write in a PLACE step.
    """
    parts = [f"{goal.obj} {goal.direction} {goal.ref}" for goal in problem.goal]
    return "Put " + " and ".join(parts) + "."


def format_history(history: Sequence[DiscreteAction]) -> str:
    """Executed actions as numbered tuples in the reply's own notation, oldest first."""
    if not history:
        return NO_HISTORY
    return "\n".join(
        f"{index}. ({', '.join(repr(item) for item in action.as_tuple())})"
        for index, action in enumerate(history, start=1)
    )


def _names(names: Sequence[str]) -> str:
    return ", ".join(names) if names else "(none)"


def saycan_prompt(problem: Problem, history: Sequence[DiscreteAction]) -> Prompt:
    """The prompt for one SayCan decision after ``history`` has been executed."""
    vocabulary = Vocabulary.from_problem(problem)
    user = _fill(
        "saycan_user",
        instruction=task_instruction(problem),
        movables=_names(vocabulary.movables),
        regions=_names(vocabulary.regions),
        doors=_names(vocabulary.doors),
        history=format_history(history),
    )
    return Prompt(system=_fill("saycan_system"), user=user)
