"""What the predicate engine keeps for one state (Appendix A's cache), and edits of it.

Every sampled motion of a state -- the base routes, the picks, the placements -- lives in one
:class:`PredicateCache` with the swept collisions of each; the literals are derived from those.
An edit that must touch every motion (an object left its pose; an object stands somewhere new)
goes through :func:`map_motions`, so the four kinds of sample are handled alike.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TypeVar

from stalm.motion.colliders import Collider
from stalm.motion.manipulation import PARKED
from stalm.motion.sweeps import ArmSegment, ObjectAt, SweptMotion, sweep_near
from stalm.predicates.deadline import Deadline, check
from stalm.predicates.literals import GroundLiteral
from stalm.predicates.samples import PickRecord, PlacementSample
from stalm.world.scene import Sim
from stalm.world.state import Grasp, ObjectPose, State

Key = TypeVar("Key", bound=tuple[str, ...])
Samples = tuple[PlacementSample, ...]


@dataclass
class PredicateCache:
    """Everything computed for one state; :meth:`PredicateEngine.update` derives the next."""

    state: State
    literals: frozenset[GroundLiteral]
    base: dict[str, SweptMotion] = field(default_factory=dict)
    picks: dict[str, PickRecord] = field(default_factory=dict)
    placements: dict[tuple[str, str], tuple[PlacementSample, ...]] = field(default_factory=dict)
    targeted: dict[tuple[str, str, str], tuple[PlacementSample, ...]] = field(default_factory=dict)
    grasps: dict[str, tuple[Grasp, float]] = field(default_factory=dict)
    unreachable: set[str] = field(default_factory=set)
    swept_motions: int = 0
    relevant: frozenset[str] | None = None
    """The objects the literals are computed for (None: every object; see
    ``PredicateSettings.relevant_only``)."""


def map_motions(
    cache: PredicateCache,
    change: Callable[[SweptMotion], SweptMotion],
    drop_placements_of: str | None = None,
) -> None:
    """Replace every motion of ``cache`` by ``change(motion)`` (in place), leaving out the
    placement samples of ``drop_placements_of`` (an object whose own samples are redrawn)."""

    def samples(entries: dict[Key, tuple[PlacementSample, ...]]) -> dict[Key, Samples]:
        return {
            key: tuple(PlacementSample(s.pose, change(s.motion)) for s in value)
            for key, value in entries.items()
            if key[0] != drop_placements_of
        }

    cache.base = {key: change(motion) for key, motion in cache.base.items()}
    cache.picks = {
        key: replace(record, motions=tuple(change(m) for m in record.motions))
        for key, record in cache.picks.items()
    }
    cache.placements = samples(cache.placements)
    cache.targeted = samples(cache.targeted)


def forget_object(cache: PredicateCache, obj: str) -> None:
    """Drop every collision with ``obj`` (it left its pose) and its own placement samples."""

    def strip(motion: SweptMotion) -> SweptMotion:
        return motion if obj not in motion.hits else replace(motion, hits=motion.hits - {obj})

    map_motions(cache, strip, drop_placements_of=obj)


def resweep_near(
    cache: PredicateCache,
    collider: Collider,
    obj: str,
    pose: ObjectPose,
    radius: float,
    deadline: Deadline | None,
) -> None:
    """Test the motions of ``cache`` that pass near ``obj``'s new ``pose`` against it, and it
    alone (the rest of the world did not move); ``radius``: its extent seen from above."""
    sim = collider.sim
    body = sim.bodies.objects[obj]

    def again(motion: SweptMotion) -> SweptMotion:
        if not motion.near(pose.x, pose.y, radius):
            return motion
        check(deadline)
        cache.swept_motions += 1
        sim.place_object(obj, pose)
        hit = sweep_near(collider, motion, body, pose.x, pose.y, radius)
        _restore_subjects(sim, cache.state, motion)
        sim.place_object(obj, pose)
        return replace(motion, hits=motion.hits | {obj}) if hit else motion

    map_motions(cache, again)


def _restore_subjects(sim: Sim, state: State, motion: SweptMotion) -> None:
    """Put back the objects a sweep carried or placed (a pick's or placement's subject)."""
    for segment in motion.segments:
        moved = segment.obj if isinstance(segment, ObjectAt) else None
        if isinstance(segment, ArmSegment) and segment.held is not None:
            moved = segment.held.obj
        if moved is None:
            continue
        if state.has_pose(moved):
            sim.place_object(moved, state.pose(moved))
        else:
            sim.place_object(moved, PARKED)


def holds(cache: PredicateCache, obj: str) -> bool:
    """Whether ``obj`` is held in the cache's state."""
    return cache.state.held is not None and cache.state.held.obj == obj


def fewest(sets: object) -> frozenset[str] | None:
    """The smallest of ``sets`` of blockers (the first of that size; stops at an empty one),
    None if there are none."""
    best: frozenset[str] | None = None
    for hits in sets:  # type: ignore[attr-defined]
        if best is None or len(hits) < len(best):
            best = frozenset(hits)
            if not best:
                break
    return best
