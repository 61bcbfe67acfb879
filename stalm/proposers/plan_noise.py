"""Figure 5's three kinds of task-plan error, made on purpose (the noisy proposer's corruptions).

Offline, the symbolic proposer with geometric feedback mostly hands Concretize a goal plan, so
the warm-started tree has nothing to repair, and the embedded 135M model errs so much that the
tree does everything alone. To measure what the tree is worth between those two, a proposer
makes the paper's mistakes at a set rate (:mod:`stalm.proposers.noisy`); the mistakes are the
ones §4.4 describes, made from a plan that was good:

* **precondition violation**: the step that clears an occluder (a pick and place of an object
  the state's ``PickOccludedBy``/``PlaceOccludedBy`` literals name for a later step) or opens
  the door in the way is dropped, so a later pick or place is occluded -- "pick the goal object
  despite being occluded". The last placement of a goal object is never the dropped step (that
  would also leave the goal short);
* **lack of 3D understanding**: of the objects a plan puts into one region, the one with the
  largest footprint (at least :data:`LARGER_FOOTPRINT` times that of the first one put there)
  is moved in front of the others -- "the LLM often tries to place the grill to the goal first
  in P5 and P6". It moves no earlier than the steps it needs itself (opening a door, clearing
  its own occluders, an earlier move of it or of its reference object), so the plan's
  predicates still hold and only the geometry is wrong. Among P1-P6 only the grill (P5, P6)
  and the plate (P4) are that much larger than what else is put beside them: elsewhere the
  kind does not apply, since reordering cans of one size is no error;
* **partially achieved goal**: the plan is cut before the placements of its last goal objects
  (one or more, the number drawn) -- "a task plan that satisfies only four out of six goals".

Only kinds that apply to a plan are drawn, so the share of corrupted plans is the rate whenever
one does; a plan drawn for corruption that none applies to stays as it was and says so
(``inapplicable``). Every plan takes exactly three draws from the generator whatever happens to
it, so two runs with one seed and different rates corrupt nested sets of plans (a plan
corrupted at rate 0.25 is corrupted, the same way, at 0.5).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.predicates.literals import GroundLiteral
from stalm.settings.tree import NOISE_KINDS, NoiseKind
from stalm.world.problem import Problem

NoiseLabel = Literal["clean", "inapplicable", NoiseKind]
"""What the noisy proposer did to one plan: nothing (``clean``: not drawn for corruption),
nothing although drawn (``inapplicable``: no kind applies to it), or the kind it injected."""

LARGER_FOOTPRINT = 1.5
"""How much larger (footprint area) an object must be than the first one a plan puts into its
region for putting it there first to count as a 3D mistake: the grill is about 20 times a can,
the plate 8 times a bottle; a bottle is 1.1 times a salter, which is no mistake to reorder."""

TaskSteps = tuple[DiscreteAction, ...]


@dataclass(frozen=True)
class PlanContext:
    """What the corruptions read besides a plan, all of the state the plan starts from: the
    goal's objects, each object's footprint, the region each resting object is on, and the
    occluders the literals name for each pick and place."""

    goal_objects: frozenset[str]
    footprints: tuple[tuple[str, float], ...]
    regions_of: tuple[tuple[str, str], ...]
    occluders: tuple[tuple[tuple[str, ...], frozenset[str]], ...]

    @staticmethod
    def of(problem: Problem, literals: Iterable[GroundLiteral]) -> PlanContext:
        objects = problem.spec.objects
        footprints = [(o.name, 4.0 * o.half_extents[0] * o.half_extents[1]) for o in objects]
        regions: dict[str, str] = {}
        occluders: dict[tuple[str, ...], set[str]] = {}
        for literal in literals:
            args = literal.args
            if literal.name == "AtPosition" and args[1] == "on":
                regions[args[0]] = args[2]
            elif literal.name == "PickOccludedBy":
                occluders.setdefault(("pick", args[0]), set()).add(args[1])
            elif literal.name == "PlaceOccludedBy":
                occluders.setdefault(("place", *args[:3]), set()).add(args[3])
        return PlanContext(
            goal_objects=frozenset(atom.obj for atom in problem.goal),
            footprints=tuple(footprints),
            regions_of=tuple(sorted(regions.items())),
            occluders=tuple(sorted((k, frozenset(v)) for k, v in occluders.items())),
        )

    def occluders_of(self, action: DiscreteAction) -> frozenset[str]:
        """What the literals say is in the way of ``action`` (nothing for OPEN)."""
        return dict(self.occluders).get(action.as_tuple(), frozenset())

    def footprint(self, obj: str) -> float:
        return dict(self.footprints).get(obj, 0.0)


def _units(plan: TaskSteps) -> list[tuple[int, int]]:
    """The plan as [start, end) ranges: a pick with the place of its object right after it is
    one move (two steps); any other step is a unit of its own."""
    units: list[tuple[int, int]] = []
    index = 0
    while index < len(plan):
        step = plan[index]
        following = plan[index + 1] if index + 1 < len(plan) else None
        if isinstance(step, Pick) and isinstance(following, Place) and following.obj == step.obj:
            units.append((index, index + 2))
            index += 2
        else:
            units.append((index, index + 1))
            index += 1
    return units


def _moved(plan: TaskSteps, unit: tuple[int, int]) -> Place | None:
    """The placement of a move unit (None for a unit that is no pick-and-place)."""
    start, end = unit
    last = plan[end - 1]
    return last if end - start == 2 and isinstance(last, Place) else None


def _last_goal_moves(
    plan: TaskSteps, units: Sequence[tuple[int, int]], goal: frozenset[str]
) -> dict[str, int]:
    """Per goal object the plan moves: the index (into ``units``) of its last move."""
    last: dict[str, int] = {}
    for k, unit in enumerate(units):
        place = _moved(plan, unit)
        if place is not None and place.obj in goal:
            last[place.obj] = k
    return last


def precondition_violations(plan: TaskSteps, context: PlanContext) -> list[TaskSteps]:
    """The plan without one step that clears the way for a later one, for each such step: an
    OPEN of a door, or a move of an object (not a goal object's last move), that the literals
    name as an occluder of a later pick or place of the plan."""
    units = _units(plan)
    keep = set(_last_goal_moves(plan, units, context.goal_objects).values())
    variants: list[TaskSteps] = []
    for k, (start, end) in enumerate(units):
        first = plan[start]
        place = _moved(plan, (start, end))
        if isinstance(first, Open):
            cleared = first.door
        elif place is not None and k not in keep:
            cleared = place.obj
        else:
            continue
        if any(cleared in context.occluders_of(later) for later in plan[end:]):
            variants.append(plan[:start] + plan[end:])
    return variants


def crowded_reorders(plan: TaskSteps, context: PlanContext) -> list[TaskSteps]:
    """For each region the plan puts several objects into whose largest is put there after a
    much smaller one: the plan with that largest object's move brought forward to before the
    first placement into the region it can precede (see the module docstring)."""
    units = _units(plan)
    where = dict(context.regions_of)
    into: dict[str, list[int]] = {}
    for k, unit in enumerate(units):
        place = _moved(plan, unit)
        if place is None:
            continue
        region = place.ref if place.direction == "on" else where.get(place.ref)
        if region is None:
            continue
        where[place.obj] = region
        into.setdefault(region, []).append(k)
    variants: list[TaskSteps] = []
    for ks in into.values():
        if len(ks) < 2:
            continue
        first = _object(plan, units[ks[0]])
        big = max(ks[1:], key=lambda k: context.footprint(_object(plan, units[k])))
        obj = _object(plan, units[big])
        if context.footprint(obj) < LARGER_FOOTPRINT * context.footprint(first):
            continue
        earliest = _earliest(plan, units, big, context)
        targets = [k for k in ks if earliest <= k < big]
        if not targets:
            continue
        order = [*range(targets[0]), big, *(k for k in range(targets[0], len(units)) if k != big)]
        variants.append(tuple(step for k in order for step in plan[slice(*units[k])]))
    return variants


def _object(plan: TaskSteps, unit: tuple[int, int]) -> str:
    place = _moved(plan, unit)
    assert place is not None
    return place.obj


def _earliest(
    plan: TaskSteps, units: Sequence[tuple[int, int]], k: int, context: PlanContext
) -> int:
    """The first unit index move ``k`` may be brought forward to: after every earlier unit that
    opens a door, or moves the object itself, its reference, or what the literals say is in the
    way of its pick or its place."""
    start, _ = units[k]
    pick, place = plan[start], plan[start + 1]
    assert isinstance(place, Place)
    needs = {place.obj, place.ref} | context.occluders_of(pick) | context.occluders_of(place)
    earliest = 0
    for j in range(k):
        moved = _moved(plan, units[j])
        step = plan[units[j][0]]
        if isinstance(step, Open) or (moved is not None and moved.obj in needs):
            earliest = j + 1
    return earliest


def partial_goals(plan: TaskSteps, context: PlanContext) -> list[TaskSteps]:
    """The plan cut before the last move of its last ``j`` goal objects, for every ``j`` that
    leaves a step (one variant per ``j``, fewest goal objects left out first)."""
    units = _units(plan)
    last = sorted(_last_goal_moves(plan, units, context.goal_objects).values())
    variants: list[TaskSteps] = []
    for k in reversed(last):
        start = units[k][0]
        if start > 0:
            variants.append(plan[:start])
    return variants


CORRUPTIONS: dict[NoiseKind, Callable[[TaskSteps, PlanContext], list[TaskSteps]]] = {
    "precondition_violation": precondition_violations,
    "lack_of_3d_understanding": crowded_reorders,
    "partially_achieved_goal": partial_goals,
}
"""Each kind's corruption: every variant of a plan it can make (none: it does not apply)."""


def corrupt_plans(
    plans: Sequence[TaskSteps],
    context: PlanContext,
    rate: float,
    weights: Sequence[float],
    rng: np.random.Generator,
) -> tuple[tuple[TaskSteps, ...], tuple[NoiseLabel, ...]]:
    """Each plan corrupted with probability ``rate``, its kind drawn by ``weights`` (in the
    order of :data:`~stalm.settings.tree.NOISE_KINDS`) among the kinds that apply to it,
    and one of that kind's variants drawn; with what was done to each. Three draws per plan
    (see the module docstring)."""
    corrupted: list[TaskSteps] = []
    labels: list[NoiseLabel] = []
    for plan in plans:
        u_rate, u_kind, u_variant = rng.random(3)
        if u_rate >= rate:
            corrupted.append(plan)
            labels.append("clean")
            continue
        options = {kind: CORRUPTIONS[kind](plan, context) for kind in NOISE_KINDS}
        weighted = [
            (k, w) for k, w in zip(NOISE_KINDS, weights, strict=True) if w > 0 and options[k]
        ]
        if not weighted:
            corrupted.append(plan)
            labels.append("inapplicable")
            continue
        kind = _draw(weighted, u_kind)
        variants = options[kind]
        corrupted.append(variants[min(int(u_variant * len(variants)), len(variants) - 1)])
        labels.append(kind)
    return tuple(corrupted), tuple(labels)


def _draw(weighted: Sequence[tuple[NoiseKind, float]], u: float) -> NoiseKind:
    """The kind whose share of the total weight ``u`` (in [0, 1)) falls in."""
    total = sum(w for _, w in weighted)
    reached = 0.0
    for kind, weight in weighted:
        reached += weight / total
        if u < reached:
            return kind
    return weighted[-1][0]  # u within rounding of 1
