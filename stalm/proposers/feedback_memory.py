"""What one trial remembers of geometric feedback (:class:`FeedbackMemory`), and the evidence
that refutes a rule: every pick and placement Concretize or the search tree found feasible
(:class:`Grounded`)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field

from stalm.domain.actions import DiscreteAction, Pick, Place
from stalm.proposers.feedback import FailedStep
from stalm.search.concretize import ConcretePlan
from stalm.search.tree import SearchTree
from stalm.world.problem import Problem
from stalm.world.relations import region_of
from stalm.world.state import State


@dataclass(frozen=True)
class Grounded:
    """A pick or placement Concretize or the search tree grounded: ``action`` was feasible in
    ``state``; its object was on ``region`` (a pick) or came to rest there (a placement). It
    is the evidence that refutes a rule forbidding that action."""

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
                if key in known:
                    self._widen(key, step)
            if key not in known:
                known.add(key)
                self.steps.append(step)
                added += 1
                if step.is_rule and any(refutes(g, step) for g in self.grounded.values()):
                    self.refuted.add(key)
        return added

    def _widen(self, key: tuple[object, ...], step: FailedStep) -> None:
        """A known rule seen again with more doors open holds in those states too (a failure
        with a door open holds with it closed: :meth:`FailedStep.holds_in`), so the copy that
        applies in more states is kept."""
        for index, known in enumerate(self.steps):
            if _key(known) == key and known.open_doors < step.open_doors:
                self.steps[index] = step

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
            if step.is_rule and key in self.refuted:
                holding += [s for s in self.exact.get(key, {}).values() if s.holds_in(state)]
            elif step.holds_in(state):
                holding.append(step)
        return tuple(holding)


def _key(step: FailedStep) -> tuple[object, ...]:
    if step.is_rule:  # the symbolic rule, whatever the exact poses were
        return (step.forbids, step.forbids_pick, step.besides, step.support)
    return (step.action, step.facts, step.support, step.open_doors)
