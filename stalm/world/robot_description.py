"""A robot described as data: which URDF, which chain, which gripper, how it is mounted.

A robot file (YAML) names the URDF (a path relative to the file, or ``pybullet_data:<path>``
inside PyBullet's data), the arm's base and tool links (the tool link, moved by an optional
``tool_offset``, is the grasp frame), the gripper's finger joints held open, the mount (a
holonomic base with a lift, or fixed at a pose in the world), the carry configuration and the
limits a trajectory must keep. Joint and velocity limits are read from the URDF unless the
file gives them (a URDF's numbers are sometimes placeholders); acceleration limits are given,
since no URDF states them. The shipped robots are package data (:data:`ROBOTS_DIR`) and load by
name; any other loads by path.

This module checks what the file alone can say (types, ranges, an ordered lift range); what
needs the URDF (links that exist, a serial arm of 6 or 7 revolute joints, a carry
configuration inside the limits, a gripper opening the fingers allow) is checked by
:func:`~stalm.world.robot_loader.load_robot` through
:mod:`stalm.world.robot_urdf`. Errors name the file and the field,
as a problem file's do.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import pybullet_data
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from stalm.errors import StalmError
from stalm.files import MAX_PROBLEM_FILE_BYTES, load_yaml, read_text
from stalm.world.problem_file import format_validation_error
from stalm.world.spec_values import Coordinate, Name, Positive, Vec3

ROBOTS_DIR = Path(__file__).with_name("robots")
"""The robot files shipped with stalm, each ``<name>.yaml``, with its fitted spheres beside it."""
PYBULLET_DATA_PREFIX = "pybullet_data:"
"""A ``urdf`` starting with this names a file inside PyBullet's own data folder."""
REQUIRED_FIELDS = ("name", "urdf", "base_link", "tool_link", "mount", "carry")

LinkName = Annotated[str, Field(min_length=1, max_length=128, pattern=r"^[^\s]+$")]
"""A URDF link or joint name: URDFs allow more than identifiers (``-``, ``.``, ``/``)."""
Angle = Annotated[float, Field(ge=-100.0, le=100.0)]
"""A joint position (rad or m): a URDF joint's range is never wider than this."""
Rate = Annotated[float, Field(gt=0, le=1000.0)]
"""A velocity or acceleration limit (per second, per second squared)."""


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class ToolOffset(_Spec):
    """The grasp frame in the tool link's frame: a translation, then roll-pitch-yaw (rad)."""

    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)


class GripperSpec(_Spec):
    """A two-finger gripper held open (grasping is kinematic): the finger joints' open
    positions, the two links whose gap is the opening, and that opening (m), the gap between
    the fingers' collision geometry when open (checked against the URDF)."""

    finger_joints: dict[LinkName, Angle] = Field(min_length=1)
    finger_links: tuple[LinkName, LinkName]
    opening: Positive


class MobileMount(_Spec):
    """A holonomic disc base carrying the arm on a vertical lift, as today's robot."""

    kind: Literal["mobile"]
    base_radius: Positive
    base_height: Positive
    arm_mount_forward: Coordinate = Field(description="arm mount ahead of the base centre (m)")
    lift_range: tuple[Positive, Positive]
    carry_lift: Positive = Field(description="lift height while driving (m)")
    lift_speed: Rate
    lift_acceleration: Rate
    base_speed: Rate
    base_acceleration: Rate
    base_turn_rate: Rate
    base_turn_acceleration: Rate

    @model_validator(mode="after")
    def _lift_in_range(self) -> MobileMount:
        low, high = self.lift_range
        if low >= high:
            raise ValueError(f"lift_range {self.lift_range}: the lowest height comes first")
        if not low <= self.carry_lift <= high:
            raise ValueError(f"carry_lift {self.carry_lift} is outside lift_range {low}..{high}")
        return self


class FixedMount(_Spec):
    """The arm's base link fixed at a pose in the world: a tabletop arm, no base motion."""

    kind: Literal["fixed"]
    xyz: Vec3
    yaw: Coordinate = 0.0


class RobotSpec(_Spec):
    """What a robot file says; see the module's docstring for each field's meaning."""

    name: Name
    urdf: str = Field(min_length=1, max_length=1024)
    base_link: LinkName
    tool_link: LinkName
    tool_offset: ToolOffset = ToolOffset()
    gripper: GripperSpec | None = None
    mount: Annotated[MobileMount | FixedMount, Field(discriminator="kind")]
    carry: tuple[Angle, ...] = Field(min_length=1, max_length=16)
    ready: tuple[Angle, ...] | None = Field(
        default=None,
        min_length=1,
        max_length=16,
        description="IK's first seed: the arm reaching forward at mid height (default: carry)",
    )
    joint_limits: tuple[tuple[Angle, Angle], ...] | None = None
    velocity_limits: tuple[Rate, ...] | None = None
    acceleration_limits: tuple[Rate, ...] = Field(min_length=1, max_length=16)
    sources: dict[Name, Annotated[str, Field(max_length=400)]] = Field(
        default_factory=dict, description="where given limits and offsets come from"
    )

    @model_validator(mode="after")
    def _limits_ordered(self) -> RobotSpec:
        for index, (low, high) in enumerate(self.joint_limits or ()):
            if low >= high:
                raise ValueError(f"joint_limits[{index}]: lower {low} is not below upper {high}")
        return self


@dataclass(frozen=True)
class ChainJoint:
    """One joint on the path from the base link to the tool link, as PyBullet reads it."""

    name: str
    kind: str
    """``revolute``, ``prismatic`` or ``fixed``."""
    index: int
    """PyBullet's joint index (= the child link's index)."""
    child_link: str
    lower: float
    upper: float
    velocity: float


FIXED_PEDESTAL = (0.05, 0.02)
"""Radius and height (m) of the disc a fixed arm's base body is: a marker on the floor under
its mount that nothing reaches, since the base never moves."""


@dataclass(frozen=True)
class Platform:
    """What the arm rides, as the planner moves it: a base of ``base_radius`` and
    ``base_height`` with the arm's mount ``arm_mount_forward`` ahead of its centre at a lift
    height in ``lift_range`` (``carry_lift`` while driving), and the speeds a trajectory
    keeps. A fixed arm (``fixed_at``: the base pose x, y, yaw it stands at) is a base that
    never moves under a lift of one height, its mount's; its speeds time no motion."""

    base_radius: float
    base_height: float
    arm_mount_forward: float
    lift_range: tuple[float, float]
    carry_lift: float
    lift_speed: float
    lift_acceleration: float
    base_speed: float
    base_acceleration: float
    base_turn_rate: float
    base_turn_acceleration: float
    fixed_at: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Robot:
    """A robot file validated against its URDF: the spec, and what was read from the URDF
    merged with what the file gives (the arm's joints base to tool, and their limits)."""

    spec: RobotSpec
    source: str
    """The robot file, as errors and reports name it."""
    urdf_path: Path
    urdf_sha256: str
    """Hash of the URDF's text and of every collision mesh it names: what a fitted sphere set
    is valid for."""
    chain: tuple[ChainJoint, ...]
    """Every joint from the base link to the tool link, fixed ones included."""
    joint_limits: tuple[tuple[float, float], ...]
    velocity_limits: tuple[float, ...]

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def arm_joints(self) -> tuple[ChainJoint, ...]:
        """The chain's moving joints, base to tool: what a configuration lists."""
        return tuple(joint for joint in self.chain if joint.kind != "fixed")

    @property
    def acceleration_limits(self) -> tuple[float, ...]:
        return self.spec.acceleration_limits

    @property
    def platform(self) -> Platform:
        """What the arm rides, as the planner moves it (see :class:`Platform`)."""
        mount = self.spec.mount
        if isinstance(mount, MobileMount):
            return Platform(
                mount.base_radius,
                mount.base_height,
                mount.arm_mount_forward,
                mount.lift_range,
                mount.carry_lift,
                mount.lift_speed,
                mount.lift_acceleration,
                mount.base_speed,
                mount.base_acceleration,
                mount.base_turn_rate,
                mount.base_turn_acceleration,
            )
        x, y, z = mount.xyz
        radius, height = FIXED_PEDESTAL
        return Platform(
            radius, height, 0.0, (z, z), z, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, (x, y, mount.yaw)
        )

    @property
    def carry_conf(self) -> tuple[float, ...]:
        """The lift height and arm joints while driving."""
        return (self.platform.carry_lift, *self.spec.carry)

    @property
    def gripper(self) -> GripperSpec:
        """The gripper; a StalmError for an arm without one, which cannot pick."""
        if self.spec.gripper is None:
            raise StalmError(f"{self.source}: robot {self.name!r} has no gripper: it cannot pick")
        return self.spec.gripper


def is_builtin_panda(robot: Robot) -> bool:
    """Is ``robot`` the shipped Panda's file (the one the compiled Panda code, its limits and
    its recorded plans stand for), not another file that merely names itself ``panda``?"""
    return Path(robot.source).resolve() == (ROBOTS_DIR / "panda.yaml").resolve()


def resolve_urdf(urdf: str, robot_dir: Path) -> Path:
    """The URDF file a robot file's ``urdf`` names (``pybullet_data:`` or relative to the
    robot file's folder)."""
    if urdf.startswith(PYBULLET_DATA_PREFIX):
        return Path(pybullet_data.getDataPath()) / urdf.removeprefix(PYBULLET_DATA_PREFIX)
    path = Path(urdf).expanduser()
    return path if path.is_absolute() else robot_dir / path


def parse_robot(data: object, source: str) -> RobotSpec:
    """Validate already-loaded robot data; errors name ``source`` and the field."""
    if not isinstance(data, dict):
        kind = "text" if isinstance(data, str) else type(data).__name__
        raise StalmError(f"{source}: a robot file must be a mapping of fields, got {kind}")
    if not any(name in data for name in REQUIRED_FIELDS):
        raise StalmError(
            f"{source}: not a robot file (it has none of the fields {', '.join(REQUIRED_FIELDS)})"
        )
    try:
        return RobotSpec.model_validate(data)
    except ValidationError as error:
        raise StalmError(format_validation_error(source, error)) from None


def read_robot_spec(path: Path) -> RobotSpec:
    """Read and validate a robot file (what it says alone, no URDF read)."""
    text = read_text(path, MAX_PROBLEM_FILE_BYTES, "robot file")
    return parse_robot(load_yaml(text, str(path)), str(path))
