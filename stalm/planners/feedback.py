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
* a **rule** for a placement that found no free spot beside movable objects on its region
  (P5's cans after the grill): ``Forbids``/``Needs`` facts rule it out while those objects
  are on the region, wherever exactly. That is a generalisation from a few draws of their
  poses: a placement Concretize or the search grounds while the rule's objects are on the
  region refutes it (:class:`FeedbackMemory`), after which only what was observed (the
  failure at those exact poses, ``exact``) is kept. Rules that contradict each other and
  leave no plan are given up by the proposer in a random order;
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

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.outcome import Infeasibility
from stalm.llm.feedback_prompt import FailedPlan
from stalm.predicates.literals import GroundLiteral
from stalm.search.concretize import ConcretePlan
from stalm.search.transition import PRECONDITION
from stalm.search.tree import SearchTree
from stalm.world.problem import Problem
from stalm.world.relations import region_of
from stalm.world.state import ObjectPose, State

FAILED_PICK = "PickFailed"
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
        why = step.kappa if isinstance(step.kappa, Infeasibility) else step.outcome.failure
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
        forbids, besides = _crowded_placement(problem, step.state, step.action, why)
        forbids_pick, pick_besides = _crowded_pick(problem, step.state, step.action, why)
        if forbids is not None:
            refs = [forbids[2]] if step.state.has_pose(forbids[2]) else []
            support = tuple((n, step.state.pose(n)) for n in refs)
            rule = replace(exact, forbids=forbids, besides=besides, support=support)
        elif forbids_pick is not None:
            # while the object itself stays where it was, wherever the others are
            support = ((forbids_pick[0], step.state.pose(forbids_pick[0])),)
            rule = replace(exact, forbids_pick=forbids_pick, besides=pick_besides, support=support)
        else:
            learned.append(exact)
            continue
        learned.append(replace(rule, facts=(), exact=exact))
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


def _crowded_placement(
    problem: Problem, state: State, action: DiscreteAction, why: Infeasibility
) -> tuple[tuple[str, str, str, str] | None, tuple[str, ...]]:
    """A placement with no free spot whose samples hit movable objects on the region: the
    symbolic rule 'not there while those objects are there' (P5's cans after the grill)."""
    if not isinstance(action, Place) or why.kind != "no_placement":
        return None, ()
    spec = problem.spec
    region = action.ref if action.direction == "on" else region_of(spec, state, action.ref)
    if region is None:
        return None, ()
    besides = tuple(
        sorted(
            b
            for b in why.blockers
            if b != action.obj and state.has_pose(b) and region_of(spec, state, b) == region
        )
    )
    if not besides:
        return None, ()
    return (action.obj, action.direction, action.ref, region), besides


def _crowded_pick(
    problem: Problem, state: State, action: DiscreteAction, why: Infeasibility
) -> tuple[tuple[str, str] | None, tuple[str, ...]]:
    """A pick that collided with movable objects resting on the object's own region: the
    symbolic rule 'not while those objects are there' (P5's coke behind the grill)."""
    if not isinstance(action, Pick):
        return None, ()
    spec = problem.spec
    region = region_of(spec, state, action.obj)
    if region is None:
        return None, ()
    besides = tuple(
        sorted(
            b
            for b in why.blockers
            if b != action.obj and state.has_pose(b) and region_of(spec, state, b) == region
        )
    )
    if not besides:
        return None, ()
    return (action.obj, region), besides


@dataclass(frozen=True)
class Grounded:
    """A pick or placement Concretize grounded: ``action`` was feasible in ``state``; its
    object was on ``region`` (a pick) or came to rest there (a placement). It is the evidence
    that refutes a rule forbidding that action."""

    state: State
    action: Pick | Place
    region: str
    beside: frozenset[str]
    """The other objects resting on ``region`` in ``state``."""


def _grounded(
    problem: Problem, state: State, action: DiscreteAction, after: State
) -> Grounded | None:
    """The feasible transition ``state`` → ``after`` by ``action`` as evidence, if it is a
    pick or a placement on (from) a region."""
    if not isinstance(action, Pick | Place):
        return None
    spec = problem.spec
    region = region_of(spec, state if isinstance(action, Pick) else after, action.obj)
    if region is None:
        return None
    beside = frozenset(
        n for n in state.object_names if n != action.obj and region_of(spec, state, n) == region
    )
    return Grounded(state, action, region, beside)


def grounded_steps(problem: Problem, plans: Iterable[ConcretePlan]) -> Iterator[Grounded]:
    """Every feasible pick and placement among Concretize's ``plans``."""
    for plan in plans:
        for step in plan.steps:
            if step.params is not None and step.outcome.feasible:
                found = _grounded(problem, step.state, step.action, step.outcome.state)
                if found is not None:
                    yield found


def grounded_in_tree(problem: Problem, tree: SearchTree) -> Iterator[Grounded]:
    """Every feasible pick and placement the search tree holds (its κ children whose
    transition was feasible): the simulations' evidence, and the executed actions'."""
    for state in tree.states():
        for cont in tree.node(state).children:
            for kappa in cont.children:
                if kappa.outcome.feasible:
                    found = _grounded(problem, state, cont.action, kappa.outcome.state)
                    if found is not None:
                        yield found


def refutes(grounded: Grounded, rule: FailedStep) -> bool:
    """Whether ``grounded`` is a counterexample to ``rule``: the action it forbids (for a
    placement rule about a whole region, any placement that put the object there) was
    grounded while every one of its ``besides`` was on the region, in a state where the rule
    itself applies."""
    action = grounded.action
    if not (rule.holds_in(grounded.state) and set(rule.besides) <= grounded.beside):
        return False
    if rule.forbids_pick is not None:
        return isinstance(action, Pick) and (action.obj, grounded.region) == rule.forbids_pick
    assert rule.forbids is not None
    obj, direction, ref, region = rule.forbids
    if not isinstance(action, Place) or action.obj != obj or grounded.region != region:
        return False
    return direction == "on" or (action.direction, action.ref) == (direction, ref)


@dataclass
class FeedbackMemory:
    """Every failed step learned in one trial; :meth:`holding_in` gives what applies now.

    Steps are never forgotten, only filtered by their support, so a step learned before the
    robot moved an object applies again if the object comes back. Duplicates (the same action
    failing again for the same reason in the same context) are kept once.

    A rule (``FailedStep.is_rule``) generalises from the draws that failed. Its failures do
    not confirm it: when two rules forbid each other's order (no can after the grill, no
    grill after a can drawn at the front), every failed try of the right order counts for
    the wrong rule. What does tell is a counterexample: a pick or placement Concretize or the
    search grounded where the rule forbids it (:func:`refutes`). A refuted rule is never
    handed to the proposer again; its observations are, each scoped to the poses it was made
    at (``FailedStep.exact``): what was seen stays true, the generalisation does not.
    """

    steps: list[FailedStep] = field(default_factory=list)
    exact: dict[tuple[object, ...], dict[tuple[object, ...], FailedStep]] = field(
        default_factory=dict
    )
    """Per rule (by :func:`_key`), its observations scoped to their exact poses, each
    distinct configuration once (what is kept of the rule once it is refuted)."""
    refuted: set[tuple[object, ...]] = field(default_factory=set)
    grounded: dict[tuple[State, DiscreteAction], Grounded] = field(default_factory=dict)
    """Every pick and placement grounded so far, by state and action: the evidence against
    rules learned later too."""

    @staticmethod
    def empty() -> FeedbackMemory:
        return FeedbackMemory()

    def learn(self, new: Sequence[FailedStep]) -> int:
        """Add ``new`` steps; returns how many lessons were not known yet (a refuted rule's
        observation at poses not seen before counts: the proposer gets it)."""
        known = {_key(s) for s in self.steps}
        added = 0
        for step in new:
            key = _key(step)
            if step.is_rule:
                scoped = self.exact.setdefault(key, {})
                if step.exact is not None and _key(step.exact) not in scoped:
                    scoped[_key(step.exact)] = step.exact
                    added += key in self.refuted
            if key not in known:
                known.add(key)
                self.steps.append(step)
                added += 1
                if step.is_rule and any(refutes(g, step) for g in self.grounded.values()):
                    self.refuted.add(key)
        return added

    def observe(self, grounded: Iterable[Grounded]) -> int:
        """Remember picks and placements found feasible (:func:`grounded_steps` of
        Concretize's plans, :func:`grounded_in_tree`); returns how many rules they refute that
        were not refuted yet."""
        new = []
        for found in grounded:
            if (found.state, found.action) not in self.grounded:
                self.grounded[(found.state, found.action)] = found
                new.append(found)
        refuted = 0
        for step in self.steps:
            key = _key(step)
            if not step.is_rule or key in self.refuted:
                continue
            if any(refutes(found, step) for found in new):
                self.refuted.add(key)
                refuted += 1
        return refuted

    def holding_in(self, state: State) -> tuple[FailedStep, ...]:
        """The steps that apply in ``state``: each rule, or, once refuted, its exact
        observations whose poses still hold."""
        holding: list[FailedStep] = []
        for step in self.steps:
            key = _key(step)
            if not step.is_rule:
                if step.holds_in(state):
                    holding.append(step)
            elif key in self.refuted:
                holding += [s for s in self.exact.get(key, {}).values() if s.holds_in(state)]
            elif step.holds_in(state):
                holding.append(step)
        return tuple(holding)


def _key(step: FailedStep) -> tuple[object, ...]:
    if step.is_rule:  # the symbolic rule, whatever the exact poses were
        return (step.forbids, step.forbids_pick, step.besides, step.support)
    return (step.action, step.facts, step.support, step.open_doors)
