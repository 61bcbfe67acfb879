"""The literals of a state that need no motion planning: hand, doors and AtPosition.

They are read off the state itself (the held object, the closed doors, which region
supports each resting object and where it stands relative to its neighbours there), so an
engine without occlusion (Table 4's prompt ablation) computes only these, at no cost.
"""

from __future__ import annotations

from stalm.predicates.literals import GroundLiteral
from stalm.world.relations import direction_between, supporting_region
from stalm.world.spec import ProblemSpec
from stalm.world.state import State


def add_symbolic(spec: ProblemSpec, state: State, literals: set[GroundLiteral]) -> dict[str, str]:
    """Add the symbolic literals of ``state`` to ``literals``; return each resting object's
    region (the occlusion literals place relative to objects on the same region)."""
    if state.held is None:
        literals.add(GroundLiteral("HandAvailable"))
    else:
        literals.add(GroundLiteral("RobotHolding", (state.held.obj,)))
    for door in spec.doors:
        if not state.is_open(door.name):
            literals.add(GroundLiteral("IsClosed", (door.name,)))
    regions_of = resting_regions(spec, state)
    for name, support in regions_of.items():
        literals.add(GroundLiteral("AtPosition", (name, "on", support)))
    for name, support in regions_of.items():
        for other, other_support in regions_of.items():
            if other != name and other_support == support:
                direction = direction_between(
                    spec.region(support), state.pose(name), state.pose(other)
                )
                literals.add(GroundLiteral("AtPosition", (name, direction, other)))
    return regions_of


def resting_regions(spec: ProblemSpec, state: State) -> dict[str, str]:
    """Each resting object's supporting region, in the state's order of objects."""
    regions_of: dict[str, str] = {}
    for name, pose in state.poses:
        support = supporting_region(spec, pose)
        if support is not None:
            regions_of[name] = support
    return regions_of
