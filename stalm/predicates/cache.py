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

from stalm.motion.sweeps import SweptMotion
from stalm.predicates.literals import GroundLiteral
from stalm.predicates.samples import PickRecord, PlacementSample
from stalm.world.state import Grasp, State

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
