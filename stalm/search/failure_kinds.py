"""Figure 5's failure kinds, judged as the paper judges them (§4.4).

Concretize (:mod:`stalm.search.concretize`) sees only the transition: a step whose symbolic
precondition is false is a ``precondition_violation``, and any step ψ found no κ for is a
``lack_of_3d_understanding``. The paper draws the line elsewhere: "precondition violation"
includes "task plans that start with actions that are infeasible due to occlusion" -- the
prompt told the model the action was occluded (PickOccludedBy / PlaceOccludedBy are the
preconditions ``UnsafePick`` / ``UnsafePlace`` of its domain), so planning it anyway is
ignoring the input, not missing 3D information. Lack of 3D understanding is what remains: the
predicates allowed the step, yet no motion or placement was found.

:func:`figure5_kind` applies that rule to one plan. The occlusion literals are those of the
state the failed step was tried in; the planner has them for the state it prompted from (the
root of Concretize), so occlusion is judged for a plan's first step. Later steps are tried in
states nobody computed predicates for (computing them would cost the motion planning STaLM
avoids) and keep Concretize's kind. A prompt without occlusion predicates (Table 4) told the
model nothing about occlusion, so with no occlusion literals nothing is re-classified.
"""

from __future__ import annotations

from collections.abc import Iterable

from stalm.domain.actions import DiscreteAction, Pick, Place
from stalm.predicates.literals import GroundLiteral
from stalm.search.concretize import ConcretePlan, ConcretizeResult, FailureKind


def occluded_in(action: DiscreteAction, literals: Iterable[GroundLiteral]) -> bool:
    """Whether ``literals`` say ``action`` is occluded (PickOccludedBy(o, ·) for PICK(o),
    PlaceOccludedBy(o, dir, ref, ·) for PLACE(o, dir, ref); OPEN is never occluded)."""
    if isinstance(action, Pick):
        return any(
            literal.name == "PickOccludedBy" and literal.args[0] == action.obj
            for literal in literals
        )
    if isinstance(action, Place):
        target = (action.obj, action.direction, action.ref)
        return any(
            literal.name == "PlaceOccludedBy" and literal.args[:3] == target for literal in literals
        )
    return False


def figure5_kind(plan: ConcretePlan, root_literals: Iterable[GroundLiteral]) -> FailureKind | None:
    """The paper's failure kind of ``plan`` (None if it reached the goal).

    ``root_literals`` are the predicates of the state Concretize started from (the prompt's
    init). A first step that failed although its precondition held is a precondition
    violation when those literals say it is occluded; otherwise Concretize's kind stands.
    """
    if (
        plan.failure == "lack_of_3d_understanding"
        and plan.failed_step == 0
        and occluded_in(plan.steps[0].action, root_literals)
    ):
        return "precondition_violation"
    return plan.failure


def figure5_kinds(
    result: ConcretizeResult, root_literals: Iterable[GroundLiteral]
) -> tuple[FailureKind, ...]:
    """:func:`figure5_kind` of every failed plan of ``result``, in order."""
    literals = frozenset(root_literals)
    kinds = (figure5_kind(plan, literals) for plan in result.plans)
    return tuple(kind for kind in kinds if kind is not None)
