"""The mobile manipulator: a holonomic disc base with a vertical lift carrying a Franka Panda.

The base moves kinematically in (x, y, yaw). The lift is the arm mount's height above the
floor, chosen per grasp by IK (so the same robot reaches counters at ~1 m and the shelf), as
the PR2's torso did in the paper. The gripper stays open; grasping is kinematic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

BASE_RADIUS = 0.3
"""Radius of the base disc (m); also the footprint the roadmap plans for."""
BASE_HEIGHT = 0.35
ARM_MOUNT_FORWARD = 0.15
"""The arm's mount sits this far ahead of the base centre, toward the region it faces."""
LIFT_RANGE = (0.55, 1.45)
"""Heights of the arm's mount above the floor that the lift can reach (m)."""
CARRY_LIFT = 0.85
"""Lift height while driving (keeps the arm below the shelf board and above tables' edges)."""
CARRY_ARM = (0.0, -1.7, 0.0, -3.0, 0.0, 1.5, 0.785)
"""Arm joints while driving: the hand folded back over the base. Seen from above, the arm's
collision shapes then reach 0.325 m from the base centre (``stalm robot check panda``), 2.5 cm
past the 0.3 m disc and 5 mm past the 0.32 m cylinder the base roadmap is checked with; kept
as it is, since every recorded plan drives with it."""
ARM_JOINT_LIMITS = (
    (-2.8973, 2.8973),
    (-1.7628, 1.7628),
    (-2.8973, 2.8973),
    (-3.0718, -0.0698),
    (-2.8973, 2.8973),
    (-0.0175, 3.7525),
    (-2.8973, 2.8973),
)
FINGER_OPENING = 0.04
"""Each finger's opening (m): the gripper stays fully open; grasping is kinematic."""
GRIPPER_GAP = 0.0778
"""The gap between the fingers' collision shapes with the gripper fully open (m, measured in
PyBullet): the widest an object may be across where the fingers close on it. Every grasp is
derived from this and :data:`GRIPPER_PALM_DEPTH`, so another gripper changes these two."""
GRIPPER_PALM_DEPTH = 0.035
"""How far the palm sits behind the grasp frame along the approach (m, measured in PyBullet):
a grasp frame deeper than this inside an object would put the palm into it."""
GRASP_FRAME = "panda_grasptarget"
"""The URDF link a grasp is expressed in (the point between the fingertips)."""
MOUNT_DESCRIPTION = "holonomic disc base (x, y, yaw) with a vertical lift carrying the arm"
"""How the arm is mounted, as an exported trajectory describes the robot."""


@dataclass(frozen=True)
class ArmMount:
    """Where the arm's base frame sits for a base pose and lift height."""

    x: float
    y: float
    z: float
    yaw: float


def arm_mount(
    base: tuple[float, float, float], lift: float, forward: float = ARM_MOUNT_FORWARD
) -> ArmMount:
    """The arm base frame for a base pose (x, y, yaw) and a lift height, the mount ``forward``
    of the base centre (a robot file's ``arm_mount_forward``; the Panda's by default)."""
    x, y, yaw = base
    return ArmMount(x + forward * math.cos(yaw), y + forward * math.sin(yaw), lift, yaw)


CARRY_CONF = (CARRY_LIFT, *CARRY_ARM)
"""Lift and arm joints while driving."""


def unfold(
    conf: tuple[float, ...], carry: tuple[float, ...] = CARRY_CONF
) -> list[tuple[float, ...]]:
    """Waypoints from the driving configuration ``carry`` (lift, arm) up (or down) to
    ``conf``'s lift height with the arm still folded: the lift moves first, so the arm never
    sweeps forward under a shelf on its way up."""
    return [carry, (conf[0], *carry[1:])]


def fold(conf: tuple[float, ...], carry: tuple[float, ...] = CARRY_CONF) -> list[tuple[float, ...]]:
    """Waypoints back from ``conf``'s lift height to the driving configuration, arm first."""
    return [(conf[0], *carry[1:]), carry]
