"""Geometric feedback (beyond the paper): failed Concretize steps as knowledge for the proposer.

Concretize knows which step of which task plan ψ could not ground, why (``no_placement``,
``arm_collision``, ``base_path_blocked``, ...) and what was in the way. Srivastava et al. (ICRA
2014) turned exactly such failures into facts for the task planner; IDTMP scoped them to the
context they were learned in. Here each failed step becomes a :class:`FailedStep`:

* **facts** for a planner that reads PDDL: the bodies in the way become occlusion literals
  (``PickOccludedBy(o, b)``, ``PlaceOccludedBy(o, dir, ref, b)``), cleared in the PDDL by
  picking ``b`` as any occlusion is; a failure with nobody to blame becomes
  ``PickFailed(o, r)`` or ``PlaceFailed(o, dir, ref, r)`` with ``r`` the region concerned, and
  ``PlaceFailed(o, on, r, r)`` also rules out every relative placement on ``r`` (no room for
  ``o`` anywhere on ``r``). They hold while ``r`` is untouched: picking another object
  from ``r`` may make room, and clears them; picking ``o`` itself does not (it cannot make
  room for itself), so ``o`` is not put back where it did not fit
  (:func:`stalm.llm.pddl.domain_pddl` with ``feedback``);
* **text** for a language model: the plan, the failed step and the transition's reason, in the
  Iterative-Replanning feedback's words (:mod:`stalm.llm.feedback_prompt`);
* a **rule** for a placement that found no free spot beside movable objects on its region,
  or whose arm hit such objects on its way in (P5's cans after the grill): ``Forbids``/
  ``Needs`` facts rule it out while those objects are on the region, wherever exactly. That
  is a generalisation from a few draws of their poses: a placement Concretize or the search
  grounds while the rule's objects are on the region refutes it
  (:mod:`stalm.proposers.feedback_memory`), after which only what was observed (the failure
  at those exact poses, ``exact``) is kept. Rules that contradict each
  other and leave no plan are given up by the proposer in a random order;
* a **rule** for a pick that collided with movable objects on the region its object rests on
  (P5's coke behind the grill): ``ForbidsPick``/``Needs`` facts rule it out while those
  objects are on that region, wherever exactly. The PDDL clears an occlusion by picking the
  occluder and predicts none from a placement, so without it the proposer's cheapest way
  past the occlusion is to put the occluder back down on the same region, and the exact
  lesson (the occlusion at the occluder's new pose) never applies where it plans from. It is
  refuted like the placement rule;
* a **support**: the poses of the objects and the door states the failure depended on. A step
  learned in one state holds in any state where every supporting object still sits where it
  sat and no door it saw closed is open (objects added elsewhere and closed doors only add
  obstacles); once the part of the state it was about changes, it no longer applies.

Symbolic failures (a false precondition) teach nothing the PDDL does not already know, and
are not kept.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.outcome import Infeasibility
from stalm.llm.feedback_prompt import FailedPlan
from stalm.predicates.literals import GroundLiteral
from stalm.search.concretize import ConcretePlan
from stalm.search.transition import PRECONDITION
from stalm.world.problem import Problem
from stalm.world.relations import region_of
from stalm.world.state import ObjectPose, State

FAILED_PICK = "PickFailed"
CROWDING_KINDS = frozenset({"no_placement", "arm_collision"})
"""The placement failures that blame the objects on the target region as a whole: no free
spot beside them, or the arm hitting them on its way in."""
FAILED_PLACE = "PlaceFailed"


@dataclass(frozen=True)
class FailedStep:
    """One task-plan step ψ found infeasible, what it teaches and where that holds.

    ``plan`` is the task plan it belonged to (for the language model's feedback), ``step`` the
    index of the failed action in it; ``facts`` are the PDDL literals it adds; ``support`` the
    poses (and ``open_doors`` the door states) the failure depended on.
    """

    plan: tuple[DiscreteAction, ...]
    step: int
    failure: Infeasibility
    facts: tuple[GroundLiteral, ...]
    support: tuple[tuple[str, ObjectPose], ...]
    open_doors: frozenset[str]
    forbids: tuple[str, str, str, str] | None = None
    """A placement (object, direction, reference, region) that found no free spot beside
    movable objects: ruled out symbolically while every one of ``besides`` is on the region,
    wherever exactly (a generalisation: the proposer drops it if it leaves no plan)."""
    besides: tuple[str, ...] = ()
    forbids_pick: tuple[str, str] | None = None
    """A pick (object, region) that collided with movable objects resting on the region the
    object rests on: ruled out while the object and every one of ``besides`` are on that
    region, wherever exactly ``besides`` are (a generalisation, weighed like ``forbids``)."""
    exact: FailedStep | None = None
    """For a rule: the same failure scoped to the exact poses it was observed at (what is
    left of the rule once a feasible pick or placement refutes the generalisation)."""

    @property
    def action(self) -> DiscreteAction:
        return self.plan[self.step]

    @property
    def is_rule(self) -> bool:
        """A generalisation (``forbids`` or ``forbids_pick``), not an exact observation."""
        return self.forbids is not None or self.forbids_pick is not None

    def holds_in(self, state: State) -> bool:
        """True while every supporting object is where it was and no door that was closed has
        been opened. Extra objects and closed doors only add obstacles, so a step that failed
        with fewer of them fails with more: a failure learned with the door open (deep in a
        plan) holds at a root where it is still closed, not the other way round."""
        if not state.open_doors <= self.open_doors:
            return False
        return all(state.has_pose(obj) and state.pose(obj) == pose for obj, pose in self.support)

    def as_failed_plan(self) -> FailedPlan:
        """The Iterative-Replanning feedback form: the plan, its failed step and why."""
        return FailedPlan(self.plan, "lack_of_3d_understanding", str(self.failure), self.step)


def failed_steps(problem: Problem, plans: Iterable[ConcretePlan]) -> tuple[FailedStep, ...]:
    """The geometric failures among Concretize's ``plans``, one per failed plan."""
    learned: list[FailedStep] = []
    for plan in plans:
        if plan.failed_step is None:
            continue
        step = plan.steps[-1]  # Concretize stops a plan at its infeasible step
        why = step.infeasibility
        if why is None or why.kind == PRECONDITION:
            continue
        facts, support = _facts_and_support(problem, step.state, step.action, why)
        exact = FailedStep(
            plan=plan.task_plan.actions,
            step=plan.failed_step,
            failure=why,
            facts=facts,
            support=support,
            open_doors=step.state.open_doors,
        )
        learned.append(_rule(problem, step.state, step.action, exact) or exact)
    return tuple(learned)


def _facts_and_support(
    problem: Problem, state: State, action: DiscreteAction, why: Infeasibility
) -> tuple[tuple[GroundLiteral, ...], tuple[tuple[str, ObjectPose], ...]]:
    spec = problem.spec
    movables = {obj.name for obj in spec.objects}
    doors = {door.name for door in spec.doors}

    def poses(names: Iterable[str]) -> tuple[tuple[str, ObjectPose], ...]:
        return tuple(sorted((n, state.pose(n)) for n in set(names) if state.has_pose(n)))

    def resting_on(region: str | None, but: str) -> set[str]:
        if region is None:
            return set()
        return {n for n in state.object_names if n != but and region_of(spec, state, n) == region}

    if isinstance(action, Pick):
        blockers = sorted(b for b in why.blockers if b != action.obj and b in movables | doors)
        if blockers:
            facts = tuple(GroundLiteral("PickOccludedBy", (action.obj, b)) for b in blockers)
            return facts, poses([action.obj, *blockers])
        region = region_of(spec, state, action.obj)
        if region is None:
            return (), poses([action.obj])
        return (GroundLiteral(FAILED_PICK, (action.obj, region)),), poses(
            resting_on(region, "") | {action.obj}
        )
    if isinstance(action, Place):
        args = (action.obj, action.direction, action.ref)
        blockers = sorted(b for b in why.blockers if b != action.obj and b in movables | doors)
        if blockers and why.kind != "no_placement":
            # the arm or the base is in the way: moving the blocker may clear it
            facts = tuple(GroundLiteral("PlaceOccludedBy", (*args, b)) for b in blockers)
            refs = [action.ref] if action.ref in movables else []
            return facts, poses([*blockers, *refs])
        # no free spot: the region is too crowded for it (whoever the spots collided with)
        region = action.ref if action.direction == "on" else region_of(spec, state, action.ref)
        if region is None:
            return (), ()
        support = resting_on(region, action.obj)
        return (GroundLiteral(FAILED_PLACE, (*args, region)),), poses(support)
    assert isinstance(action, Open)
    return (), poses(n for n in why.blockers if n in movables)


def _rule(
    problem: Problem, state: State, action: DiscreteAction, exact: FailedStep
) -> FailedStep | None:
    """The **rule** (see the module) the failure ``exact`` generalises to, None if it is no
    crowded placement or pick: P5's grill stands in front of the walled pocket and is too tall
    to reach over, so the cans fail beside it, and the coke behind it."""
    spec, why = problem.spec, exact.failure
    if isinstance(action, Place) and why.kind in CROWDING_KINDS:
        region = action.ref if action.direction == "on" else region_of(spec, state, action.ref)
    elif isinstance(action, Pick):
        region = region_of(spec, state, action.obj)
    else:
        return None
    if region is None:
        return None
    besides = tuple(
        sorted(
            b
            for b in why.blockers
            if b != action.obj and state.has_pose(b) and region_of(spec, state, b) == region
        )
    )
    if not besides:
        return None
    rule = replace(exact, facts=(), exact=exact, besides=besides)
    if isinstance(action, Pick):  # while the object stays where it was, wherever the others are
        support = ((action.obj, state.pose(action.obj)),)
        return replace(rule, forbids_pick=(action.obj, region), support=support)
    refs = [action.ref] if state.has_pose(action.ref) else []
    forbids = (action.obj, action.direction, action.ref, region)
    return replace(rule, forbids=forbids, support=tuple((n, state.pose(n)) for n in refs))
