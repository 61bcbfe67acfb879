"""Where a robot can stand in a problem: a fixed arm works from its one pose.

A mobile robot drives to each region's standing pose. A robot whose file fixes it at a pose
(``mount: kind: fixed``) never moves its base, so a problem it works must start it there and
give every region that pose as its standing pose; this says which one does not.
"""

from __future__ import annotations

from stalm.world.robot_description import Robot
from stalm.world.spec import ProblemSpec

FIXED_POSE_TOLERANCE = 1e-6
"""How far (m, rad) a standing pose may lie from a fixed arm's: rounding, no more."""


def fixed_base_mismatch(spec: ProblemSpec, robot: Robot) -> str | None:
    """Why ``robot``, fixed at a pose, cannot work ``spec``'s problem: the robot's start and
    every region's standing pose must be that pose (the base never moves); None if it can
    (a mobile robot always can)."""
    fixed = robot.platform.fixed_at
    if fixed is None:
        return None
    poses = [("robot.base", spec.robot.base)]
    poses += [(f"region {region.name!r}'s base_pose", region.base_pose) for region in spec.regions]
    poses += [
        (f"door {door.name!r}'s base_poses[{k}]", pose)
        for door in spec.doors
        for k, pose in enumerate(door.base_poses)
    ]
    for what, pose in poses:
        if any(abs(a - b) > FIXED_POSE_TOLERANCE for a, b in zip(pose, fixed, strict=True)):
            return (
                f"{robot.source}: robot {robot.name!r} is fixed at {list(fixed)} (x, y, yaw), "
                f"but {spec.name}'s {what} is {list(pose)}: a fixed arm works from one pose"
            )
    return None
