"""Where the goal puts each object: the region of a goal relation, and whether a pair is one.

The relevance-limited predicates (``PredicateSettings.relevant_only``) compute placements
only at an object's goal, and relative placements only for the goal's own relations.
"""

from __future__ import annotations

from stalm.world.problem import Problem
from stalm.world.relations import supporting_region
from stalm.world.spec import ProblemSpec, RegionSpec
from stalm.world.state import State


def goal_region(spec: ProblemSpec, state: State, direction: str, ref: str) -> RegionSpec | None:
    """The region an object goes to for ``AtPosition(_, direction, ref)`` in ``state``: the
    region itself for ``on``, else the one ``ref`` stands on (None if it stands nowhere)."""
    if direction == "on":
        return spec.region(ref)
    if not state.has_pose(ref):
        return None
    support = supporting_region(spec, state.pose(ref))
    return spec.region(support) if support is not None else None


def goal_relation(problem: Problem, obj: str, ref: str) -> bool:
    """Does the goal place ``obj`` relative to the object ``ref``?"""
    return any(g.obj == obj and g.ref == ref and g.direction != "on" for g in problem.goal)
