"""The continuous values PDDLStream turns into PDDL objects: poses, grasps and motions.

Every value a stream produces becomes a named PDDL object (``pose_3``, ``grasp_1``,
``motion_12``) that stays in the problem for the rest of the trial: that is how PDDLStream
represents continuous parameters, and why its task planner slows down as samples accumulate
(paper §4.3). Names are lower case because Fast Downward writes plans in lower case.
"""

from __future__ import annotations

from dataclasses import dataclass

from stalm.motion.sweeps import SweptMotion
from stalm.world.state import Grasp, ObjectPose

Conf = tuple[float, ...]
SE2 = tuple[float, float, float]

POSE = "pose"
GRASP = "grasp"
MOTION = "motion"
OPTIMISTIC_PREFIX = "opt_"


@dataclass(frozen=True)
class PoseValue:
    """A resting pose of one object on one region (an initial pose or a sampled placement)."""

    obj: str
    pose: ObjectPose
    region: str


@dataclass(frozen=True)
class GraspValue:
    """A sampled gripper pitch and yaw for one object (PICK's ω_g of Table 1).

    Relative to the standing pose, every pose of an object has the same yaw (PLACE keeps the
    object's orientation relative to the robot), so the object's pose in the gripper frame
    (``grasp``) depends on the grasp alone and a PLACE can be planned for it before the PICK.
    """

    obj: str
    pitch: float
    yaw: float
    point: tuple[float, float, float]
    """The grasp point in the object's frame."""
    grasp: Grasp


@dataclass(frozen=True)
class MotionValue:
    """An arm motion at a standing pose, planned ignoring movable objects.

    ``swept`` is what is tested against each object at each known pose (``Collides`` facts);
    the base route to ``stand`` is tested separately (it depends on the stand only).
    ``crosses`` names the doors the motion (with its route) passes through while closed.
    """

    kind: str
    """'pick', 'place' or 'open'."""
    subject: str
    """The object picked or placed, or the door opened."""
    stand: SE2
    swept: SweptMotion
    waypoints: tuple[Conf, ...]
    key_conf: Conf
    """The grasp, placement or handle configuration the waypoints pass through."""
    crosses: frozenset[str]
    pose: str | None = None
    """Name of the pose object of a pick or place."""
    grasp: str | None = None
    """Name of the grasp object of a pick or place."""


def real_name(kind: str, index: int) -> str:
    return f"{kind}_{index}"


def optimistic_name(kind: str, index: int) -> str:
    return f"{OPTIMISTIC_PREFIX}{kind}_{index}"


def is_optimistic(name: str) -> bool:
    return name.startswith(OPTIMISTIC_PREFIX)
