"""Placements beside a reference: which plain samples lie there, and which need drawing.

A relative literal (``PlaceOccludedBy(o, left_of, ref, x)``) is read off the plain placement
samples of ``o`` on ``ref``'s region that lie in that direction of ``ref`` with motions that
clear ``ref`` itself (moving the reference cannot free a place beside it). Where none does,
the engine draws targeted placements for that (object, direction, reference). Both the
derivation of the literals and the shared full computation, which draws the targeted
placements up front in its worker processes, walk the same pairs: this module's.

A placement relative to a reference object counts only samples whose motion clears the
reference itself: a sample drawn against the reference, or one whose held object or hand
brushes it on the way down or back, would make the reference its own occluder
(``PlaceOccludedBy(salter, left_of, bottle2, bottle2)``), a literal no plan can satisfy since
moving the reference moves the place it names. Both causes were seen: P2's initial state had
14 such literals, from 17 samples of which 6 overlapped the reference and 11 touched it only
with the held object's or the hand's sweep (P5: 30 literals, 35 of 60 samples overlapping).
"""

from __future__ import annotations

from collections.abc import Iterator

from stalm.geometry.directions import RELATIVE_DIRECTIONS
from stalm.predicates.cache import PredicateCache
from stalm.predicates.goals import goal_relation
from stalm.predicates.samples import PlacementSample
from stalm.predicates.symbolic import resting_regions
from stalm.world.problem import Problem
from stalm.world.relations import direction_between
from stalm.world.spec import RegionSpec


def beside(
    problem: Problem,
    cache: PredicateCache,
    regions_of: dict[str, str],
    obj: str,
    region: RegionSpec,
    samples: tuple[PlacementSample, ...],
) -> Iterator[tuple[str, str, tuple[PlacementSample, ...]]]:
    """For each reference resting on ``region`` (``regions_of``: each resting object's
    region) and each direction: (direction, reference, the plain ``samples`` of ``obj`` lying
    there whose motion clears the reference; empty: none does). With relevance-limited
    predicates, only the references the goal relates ``obj`` to."""
    state = cache.state
    for ref, ref_region in regions_of.items():
        if ref == obj or ref_region != region.name:
            continue
        if cache.relevant is not None and not goal_relation(problem, obj, ref):
            continue
        ref_pose = state.pose(ref)
        for direction in RELATIVE_DIRECTIONS:
            # a motion touching the reference itself says nothing (the module docstring)
            yield (
                direction,
                ref,
                tuple(
                    s
                    for s in samples
                    if direction_between(region, s.pose, ref_pose) == direction
                    and ref not in s.motion.hits
                ),
            )


def targeted_wanted(
    problem: Problem, cache: PredicateCache
) -> set[tuple[str, str, str, RegionSpec]]:
    """The targeted placements the derivation of ``cache``'s literals will ask for, not yet
    drawn: (object, direction, reference, region) where no plain sample lies beside the
    reference."""
    regions_of = resting_regions(problem.spec, cache.state)
    wanted = set()
    for obj in cache.grasps:
        for region in problem.spec.regions:
            samples = cache.placements.get((obj, region.name), ())
            for direction, ref, matching in beside(
                problem, cache, regions_of, obj, region, samples
            ):
                if not matching and (obj, direction, ref) not in cache.targeted:
                    wanted.add((obj, direction, ref, region))
    return wanted
