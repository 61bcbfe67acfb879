"""Iterative-Replanning's feedback (§4.2, after Shinn et al.): failed plans appended to the prompt.

When a task plan fails, the baseline asks again with STaLM's prompt for the same state plus the
most recent failed plans (at most two, the paper's setting) and, for each, which step failed
and why, in the words of Concretize's failure taxonomy and the transition's reason (e.g.
"precondition violated: the robot is not holding 'salter'"). The wording lives in
``templates/feedback.txt`` and ``templates/feedback_plan.txt``; this module only fills it in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from string import Template

from stalm.domain.actions import DiscreteAction
from stalm.llm.prompt import Prompt

MAX_FAILED_PLANS = 2
"""How many failed plans the prompt carries: the paper's "up to two previously failed plans"."""

FAILURE_WORDS: dict[str, str] = {
    "precondition_violation": "precondition violated",
    "lack_of_3d_understanding": "no feasible motion or placement",
    "partially_achieved_goal": "goal not achieved",
    "unparseable": "the reply could not be read",
    "no_plan": "no plan was found",
}
"""How each failure kind of :mod:`stalm.search.concretize` is named to the model."""


@dataclass(frozen=True)
class FailedPlan:
    """A task plan that did not reach the goal, and why.

    ``kind`` is a failure kind of Concretize (``precondition_violation``, ...); ``failed_step``
    the 0-based index of the infeasible step (None when every step tried was feasible or the
    reply had no plan); ``reason`` one sentence from the transition or the parser.
    """

    plan: tuple[DiscreteAction, ...]
    kind: str
    reason: str
    failed_step: int | None = None

    def failure_text(self) -> str:
        """One line: the kind in words, the step that failed, and the reason."""
        words = FAILURE_WORDS.get(self.kind, self.kind.replace("_", " "))
        if self.failed_step is not None and self.failed_step < len(self.plan):
            step = self.plan[self.failed_step]
            return f"{words} at step {self.failed_step + 1} {_tuple_text(step)}: {self.reason}"
        return f"{words}: {self.reason}"


def _fill(name: str, **values: str) -> str:
    text = resources.files("stalm.llm").joinpath("templates", f"{name}.txt").read_text("utf-8")
    return Template(text.removesuffix("\n")).substitute(values)


def _tuple_text(action: DiscreteAction) -> str:
    return "(" + ", ".join(repr(item) for item in action.as_tuple()) + ")"


def format_plan(plan: Sequence[DiscreteAction]) -> str:
    """A plan in the reply template's notation: ``[('pick', 'x'), ('place', ...)]``."""
    return "[" + ", ".join(_tuple_text(action) for action in plan) + "]"


def feedback_text(failed: Sequence[FailedPlan]) -> str:
    """The feedback block for the most recent ``MAX_FAILED_PLANS`` of ``failed`` (oldest first)."""
    recent = list(failed)[-MAX_FAILED_PLANS:]
    blocks = [
        _fill(
            "feedback_plan",
            number=str(number),
            plan=format_plan(plan.plan),
            failure=plan.failure_text(),
        )
        for number, plan in enumerate(recent, start=1)
    ]
    return _fill("feedback", failed_plans="\n".join(blocks))


def with_feedback(prompt: Prompt, failed: Sequence[FailedPlan]) -> Prompt:
    """``prompt`` with the feedback on the most recent failed plans after its user message.

    With no failed plans the prompt is returned unchanged, so the first query of a state is
    exactly STaLM's prompt.
    """
    if not failed:
        return prompt
    return Prompt(system=prompt.system, user=f"{prompt.user}\n\n{feedback_text(failed)}")
