"""How fast the robot may move: velocity and acceleration limits of the base, the lift and the arm.

Planning is kinematic and never reads these; they time a plan for a real robot (a trajectory
that exceeds them cannot be run). The arm's velocity limits are read from its URDF (the
``velocity`` of each joint's ``<limit>``, what PyBullet reports as ``maxVelocity``), so a robot
described by another URDF brings its own. A URDF has no acceleration limits and our base and
lift are no URDF joints, so those are constants here, each with its source.
"""

from __future__ import annotations

import hashlib
import math
import xml.etree.ElementTree as ElementTree
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pybullet_data

from stalm.errors import StalmError
from stalm.world.robot_description import Robot, is_builtin_panda

ARM_URDF = "franka_panda/panda.urdf"
"""The arm's URDF, inside ``pybullet_data``: the file the scene loads."""
ARM_JOINT_NAMES = tuple(f"panda_joint{i}" for i in range(1, 8))
"""The arm's seven revolute joints, base to hand, as the URDF names them."""
LIFT_JOINT_NAME = "lift"
"""The lift is no URDF joint (the arm's mount height is set kinematically): a prismatic
joint of this name carries its trajectory."""

FRANKA_ACCELERATION = (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)
"""Joint accelerations (rad/s²) of the Panda's joints 1-7, as Franka documents them (its joint
space limits for the robot's control interface). The URDF states velocities but no
accelerations; MoveIt's Panda configuration uses a quarter of these."""

LIFT_SPEED = 0.1
"""Lift speed (m/s): Fetch's torso lift, a column of the same travel carrying an arm (its
``torso_lift_joint`` in Fetch's URDF and MoveIt configuration)."""
LIFT_ACCELERATION = 0.5
"""Lift acceleration (m/s²): Fetch's torso lift (its MoveIt configuration)."""
BASE_SPEED = 1.0
"""Speed of the base along its path (m/s), in any direction: the velocity limit per axis of
Clearpath Ridgeback's controller, a holonomic (mecanum) base made to carry arms. Bounding the
speed itself, not each axis, keeps every axis of the base's own frame within it whichever way
the base faces."""
BASE_ACCELERATION = 1.0
"""Acceleration of the base along its path (m/s²): Ridgeback's controller limit per axis."""
BASE_TURN_RATE = 1.5
"""Yaw rate of the base (rad/s): Fetch's navigation profile; Ridgeback's controller allows
4 rad/s, brisk for a base with an arm on top."""
BASE_TURN_ACCELERATION = 0.8
"""Yaw acceleration of the base (rad/s²): Fetch's navigation profile."""


@dataclass(frozen=True)
class JointLimits:
    """Velocity and acceleration bounds of named joints (rad or m, per second, per second²)."""

    names: tuple[str, ...]
    velocity: tuple[float, ...]
    acceleration: tuple[float, ...]

    def __post_init__(self) -> None:
        if not len(self.names) == len(self.velocity) == len(self.acceleration):
            raise ValueError("a limit for every joint: names, velocity and acceleration differ")
        for name, v, a in zip(self.names, self.velocity, self.acceleration, strict=True):
            if not (math.isfinite(v) and v > 0 and math.isfinite(a) and a > 0):
                raise ValueError(f"joint {name}: limits must be positive, got {v}, {a}")


@dataclass(frozen=True)
class BaseLimits:
    """The holonomic base's limits: speed and acceleration along its path (the norm of the
    (x, y) velocity and acceleration), and the yaw rate and yaw acceleration."""

    speed: float = BASE_SPEED
    acceleration: float = BASE_ACCELERATION
    turn_rate: float = BASE_TURN_RATE
    turn_acceleration: float = BASE_TURN_ACCELERATION


@dataclass(frozen=True)
class RobotLimits:
    """Every dynamic limit of the robot, and the URDF the arm's limits came from.

    ``arm`` covers a configuration as the planner writes it: the lift, then the arm's joints.
    """

    base: BaseLimits
    arm: JointLimits
    urdf: str
    urdf_sha256: str


def urdf_velocity_limits(urdf: Path, joints: Sequence[str]) -> tuple[float, ...]:
    """The ``velocity`` of each named joint's ``<limit>`` in ``urdf``; a StalmError naming the
    file and the joint if it has none (a continuous joint may omit it, but then nothing bounds
    how fast a trajectory may turn it)."""
    try:
        root = ElementTree.parse(urdf).getroot()
    except (OSError, ElementTree.ParseError) as error:
        raise StalmError(f"{urdf}: cannot read the URDF ({error})") from None
    found = {str(joint.get("name")): joint for joint in root.iter("joint")}
    limits = []
    for name in joints:
        joint = found.get(name)
        if joint is None:
            raise StalmError(f"{urdf}: no joint '{name}'")
        limit = joint.find("limit")
        text = None if limit is None else limit.get("velocity")
        try:
            value = float(text) if text is not None else math.nan
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            raise StalmError(
                f"{urdf}: joint '{name}' has no positive <limit velocity=...> (got {text!r})"
            )
        limits.append(value)
    return tuple(limits)


def panda_limits() -> RobotLimits:
    """The limits of today's robot: the Panda's velocities from its URDF, Franka's
    accelerations, the lift's and the base's constants above."""
    path = Path(pybullet_data.getDataPath()) / ARM_URDF
    velocity = urdf_velocity_limits(path, ARM_JOINT_NAMES)
    arm = JointLimits(
        (LIFT_JOINT_NAME, *ARM_JOINT_NAMES),
        (LIFT_SPEED, *velocity),
        (LIFT_ACCELERATION, *FRANKA_ACCELERATION),
    )
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return RobotLimits(BaseLimits(), arm, ARM_URDF, digest)


def limits_of(robot: Robot) -> RobotLimits:
    """The limits of ``robot``: :func:`panda_limits` for the built-in Panda (its exports stay
    as they were), else its robot file's (velocities from the URDF unless the file gives
    them, the file's accelerations, its mount's lift and base)."""
    if is_builtin_panda(robot):
        return panda_limits()
    mount = robot.platform
    arm = JointLimits(
        (LIFT_JOINT_NAME, *(joint.name for joint in robot.arm_joints)),
        (mount.lift_speed, *robot.velocity_limits),
        (mount.lift_acceleration, *robot.acceleration_limits),
    )
    base = BaseLimits(
        mount.base_speed,
        mount.base_acceleration,
        mount.base_turn_rate,
        mount.base_turn_acceleration,
    )
    return RobotLimits(base, arm, robot.spec.urdf, robot.urdf_sha256)
