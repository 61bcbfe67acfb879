"""Geometric relations of a State: which region an object rests on, and where it stands
relative to another object.

These define AtPosition for the goal test, the reward and the predicates alike. Directions are
judged in the frame of the region's standing pose (the robot's view): the dominant axis of the
offset decides; farther from the robot is ``behind_of``, nearer ``front_of``, the robot's left
``left_of`` and its right ``right_of``.
"""

from __future__ import annotations

from stalm.geometry.directions import Direction
from stalm.geometry.transforms import se2_to_local
from stalm.world.spec import ProblemSpec, RegionSpec
from stalm.world.state import ObjectPose, State

ON_HEIGHT_TOLERANCE = 0.01
"""An object rests on a region when its bottom is within this distance of the region's top."""


def rests_on(region: RegionSpec, pose: ObjectPose) -> bool:
    """True if ``pose`` stands on the region's top inside its usable area."""
    if abs(pose.z - region.top) > ON_HEIGHT_TOLERANCE:
        return False
    u, v = se2_to_local((*region.center, region.yaw), pose.x, pose.y)
    ux, uy = region.usable_size
    return abs(u) <= ux / 2 + 1e-6 and abs(v) <= uy / 2 + 1e-6


def supporting_region(problem: ProblemSpec, pose: ObjectPose) -> str | None:
    """The region an object at ``pose`` rests on, or None (e.g. held)."""
    for region in problem.regions:
        if rests_on(region, pose):
            return region.name
    return None


def direction_between(region: RegionSpec, pose: ObjectPose, ref: ObjectPose) -> Direction:
    """Where ``pose`` lies relative to ``ref`` seen from ``region``'s standing pose."""
    du, dv = _offset_in_view(region, pose, ref)
    if abs(du) > abs(dv):
        return "behind_of" if du > 0 else "front_of"
    return "left_of" if dv > 0 else "right_of"


def _offset_in_view(region: RegionSpec, pose: ObjectPose, ref: ObjectPose) -> tuple[float, float]:
    frame = region.base_pose
    pu, pv = se2_to_local(frame, pose.x, pose.y)
    ru, rv = se2_to_local(frame, ref.x, ref.y)
    return pu - ru, pv - rv


def region_of(problem: ProblemSpec, state: State, obj: str) -> str | None:
    """The region ``obj`` rests on in ``state`` (None when held or off every region)."""
    if not state.has_pose(obj):
        return None
    return supporting_region(problem, state.pose(obj))


def at_position(problem: ProblemSpec, state: State, obj: str, direction: str, ref: str) -> bool:
    """AtPosition(obj, direction, ref) evaluated geometrically in ``state``."""
    if not state.has_pose(obj):
        return False
    pose = state.pose(obj)
    if direction == "on":
        return rests_on(problem.region(ref), pose)
    if not state.has_pose(ref):
        return False
    region_name = supporting_region(problem, pose)
    if region_name is None or region_name != supporting_region(problem, state.pose(ref)):
        return False
    return direction_between(problem.region(region_name), pose, state.pose(ref)) == direction
