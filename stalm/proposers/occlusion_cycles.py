"""Cycles of pick occlusions: what the symbolic proposer sets aside when the predicate
abstraction has no plan.

An occlusion literal is a sampled claim, not a proof: the predicates name as occluders what the
sampled motion with the fewest occluders touches (§3.2), from a dozen samples an action. In a
crowded region such claims can close a cycle (picking ``item_28`` sweeps through ``item_19``
and picking ``item_19`` through ``item_28``); then no object on the cycle can ever be picked in
the abstraction, nor anything one of them occludes, and Fast Downward proves the goal
unreachable although the problem has a plan. Measured on the scale suite's 64-object problems
(seed 0): scale_060's ``can_01`` is occluded by ``blocker_01`` and ``item_28``, ``item_28`` and
``item_19`` occlude each other, and the problem's replayed witness picks ``can_01`` as soon as
``blocker_01`` has gone (its grasp avoids ``item_28``; Concretize draws up to 30 grasps where
the predicates drew 12).

When the abstraction has no plan, the proposer plans once more without the ``PickOccludedBy``
literals that lie on a cycle (both ends in one strongly connected component of the graph
"picking a is occluded by b"). Without them the pick occlusions form no cycle, so a plan of
the abstraction can free every object that no ``CannotPick`` object blocks. Every other claim
stays (not a minimum set: all of a cycle's claims go, not just enough to break it), so what
hangs behind a cycle, and the placements the cycle's objects block, are still planned
around. Concretize then checks the plan in the geometry: a pick that really is blocked fails
there and comes back as geometric feedback (:mod:`stalm.proposers.feedback`). ``CannotPick``
and ``CannotPlace`` (no motion whatever is moved) are never set aside.
"""

from __future__ import annotations

from collections.abc import Iterable

from stalm.predicates.literals import GroundLiteral


def occlusion_cycles(literals: Iterable[GroundLiteral]) -> frozenset[GroundLiteral]:
    """The ``PickOccludedBy(a, b)`` literals of ``literals`` with ``a`` reachable from ``b``
    along pick occlusions (so the two lie on one cycle)."""
    picks = [lit for lit in literals if lit.name == "PickOccludedBy"]
    blockers: dict[str, set[str]] = {}
    for lit in picks:
        blockers.setdefault(lit.args[0], set()).add(lit.args[1])
    reach: dict[str, frozenset[str]] = {}

    def reachable(start: str) -> frozenset[str]:
        if start not in reach:
            seen: set[str] = set()
            todo = [start]
            while todo:
                for nxt in blockers.get(todo.pop(), ()):
                    if nxt not in seen:
                        seen.add(nxt)
                        todo.append(nxt)
            reach[start] = frozenset(seen)
        return reach[start]

    return frozenset(lit for lit in picks if lit.args[0] in reachable(lit.args[1]))


def without_occlusion_cycles(
    literals: Iterable[GroundLiteral],
) -> tuple[frozenset[GroundLiteral], frozenset[GroundLiteral]]:
    """``literals`` without their cycles' pick occlusions, and what was set aside (empty when
    there is no cycle: a second search would be the first one again)."""
    literals = frozenset(literals)
    cycles = occlusion_cycles(literals)
    return literals - cycles, cycles
