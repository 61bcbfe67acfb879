"""The immutable world state the planner reasons over.

A :class:`State` is the paper's s = (P_o1..P_on, U_d1..U_dn, c) plus what the robot holds:
resting object poses, which doors are open, the robot configuration, and the held object with
its grasp. Every float is quantised to :data:`RESOLUTION` on construction, so a State read back
from the simulator equals the State it was set from, and search-tree nodes merge reliably.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

from stalm.geometry.transforms import wrap_angle

RESOLUTION = 1e-6
"""Quantum of every stored coordinate (metres or radians)."""


def quantize(value: float) -> float:
    """Round to :data:`RESOLUTION`; ``0.0`` instead of ``-0.0`` so hashing is stable."""
    q = round(value / RESOLUTION) * RESOLUTION
    q = round(q, 6)
    return q + 0.0


def _q(values: tuple[float, ...] | list[float]) -> tuple[float, ...]:
    return tuple(quantize(float(v)) for v in values)


@dataclass(frozen=True)
class ObjectPose:
    """A resting object's pose: position of its frame origin and yaw (objects stay upright)."""

    x: float
    y: float
    z: float
    yaw: float

    @staticmethod
    def make(x: float, y: float, z: float, yaw: float) -> ObjectPose:
        return ObjectPose(*_q((x, y, z, wrap_angle(yaw))))

    @property
    def xy(self) -> tuple[float, float]:
        return (self.x, self.y)


@dataclass(frozen=True)
class RobotConf:
    """Robot configuration: holonomic base (x, y, yaw), lift height, 7 arm joints."""

    base: tuple[float, float, float]
    lift: float
    arm: tuple[float, ...]

    @staticmethod
    def make(
        base: tuple[float, ...] | list[float], lift: float, arm: tuple[float, ...] | list[float]
    ) -> RobotConf:
        b = _q((base[0], base[1], wrap_angle(base[2])))
        return RobotConf((b[0], b[1], b[2]), quantize(lift), _q(arm))

    @property
    def joints(self) -> tuple[float, ...]:
        """Lift then arm joints: the vector arm motion interpolates."""
        return (self.lift, *self.arm)


@dataclass(frozen=True)
class Grasp:
    """Where the held object sits in the gripper frame: position and quaternion (x, y, z, w)."""

    obj: str
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]

    @staticmethod
    def make(obj: str, position: tuple[float, ...], orientation: tuple[float, ...]) -> Grasp:
        p = _q(position)
        o = tuple(round(float(v), 9) + 0.0 for v in orientation)
        return Grasp(obj, (p[0], p[1], p[2]), (o[0], o[1], o[2], o[3]))

    @property
    def pose(self) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        return (self.position, self.orientation)


@dataclass(frozen=True)
class State:
    """A snapshot of the world. Hashable; equality is what merges search-tree nodes.

    ``poses`` holds every object *not* in the hand, sorted by name; ``held`` the one in hand.
    ``held_yaw_offset`` is the held object's yaw relative to the standing pose it was picked
    from, the orientation PLACE keeps (paper §4.1, assumption 4).
    """

    poses: tuple[tuple[str, ObjectPose], ...]
    open_doors: frozenset[str]
    robot: RobotConf
    held: Grasp | None = None
    held_yaw_offset: float = 0.0
    _pose_map: dict[str, ObjectPose] = field(
        default_factory=dict, init=False, repr=False, compare=False, hash=False
    )

    def __post_init__(self) -> None:
        names = [name for name, _ in self.poses]
        if names != sorted(names):
            object.__setattr__(self, "poses", tuple(sorted(self.poses)))
        object.__setattr__(self, "_pose_map", dict(self.poses))
        if self.held is not None and self.held.obj in self._pose_map:
            raise ValueError(f"'{self.held.obj}' cannot be both held and resting")

    @cached_property
    def object_names(self) -> tuple[str, ...]:
        names = [name for name, _ in self.poses]
        if self.held is not None:
            names.append(self.held.obj)
        return tuple(sorted(names))

    def pose(self, name: str) -> ObjectPose:
        """The resting pose of ``name``; KeyError if it is held or unknown."""
        return self._pose_map[name]

    def has_pose(self, name: str) -> bool:
        return name in self._pose_map

    @property
    def hand_empty(self) -> bool:
        return self.held is None

    def is_open(self, door: str) -> bool:
        return door in self.open_doors

    def with_changes(
        self,
        *,
        poses: dict[str, ObjectPose] | None = None,
        remove: str | None = None,
        robot: RobotConf | None = None,
        held: Grasp | str | None = "keep",
        held_yaw_offset: float | None = None,
        open_door: str | None = None,
    ) -> State:
        """A new State with some parts replaced (``held=None`` empties the hand)."""
        pose_map = dict(self._pose_map)
        if remove is not None:
            pose_map.pop(remove)
        if poses:
            pose_map.update(poses)
        doors = self.open_doors | {open_door} if open_door else self.open_doors
        new_held = self.held if held == "keep" else held
        assert not isinstance(new_held, str)
        return State(
            poses=tuple(sorted(pose_map.items())),
            open_doors=frozenset(doors),
            robot=robot if robot is not None else self.robot,
            held=new_held,
            held_yaw_offset=quantize(held_yaw_offset)
            if held_yaw_offset is not None
            else self.held_yaw_offset,
        )

    def to_json(self) -> dict[str, object]:
        """Plain JSON form, used by result files and ``stalm render --state``."""
        return {
            "poses": {name: [p.x, p.y, p.z, p.yaw] for name, p in self.poses},
            "open_doors": sorted(self.open_doors),
            "robot": {
                "base": list(self.robot.base),
                "lift": self.robot.lift,
                "arm": list(self.robot.arm),
            },
            "held": None
            if self.held is None
            else {
                "obj": self.held.obj,
                "position": list(self.held.position),
                "orientation": list(self.held.orientation),
            },
            "held_yaw_offset": self.held_yaw_offset,
        }

    @staticmethod
    def from_json(data: dict[str, object]) -> State:
        """The inverse of :meth:`to_json`. A State file may come from anywhere: anything
        malformed (a missing field, a wrong type, a number that is not finite) raises
        ValueError naming the field."""
        if not isinstance(data, dict):
            raise ValueError("a State is a JSON object")
        poses_raw, robot_raw = data.get("poses"), data.get("robot")
        if not isinstance(poses_raw, dict):
            raise ValueError("'poses' must map object names to [x, y, z, yaw]")
        if not isinstance(robot_raw, dict):
            raise ValueError("'robot' must be an object with 'base', 'lift' and 'arm'")
        poses = []
        for name, value in poses_raw.items():
            poses.append((name, ObjectPose.make(*_finite(value, 4, f"poses.{name}"))))
        held_raw = data.get("held")
        held = None
        if held_raw is not None:
            if not isinstance(held_raw, dict) or not isinstance(held_raw.get("obj"), str):
                raise ValueError("'held' must be null or an object with 'obj', 'position', ...")
            held = Grasp.make(
                held_raw["obj"],
                _finite(held_raw.get("position"), 3, "held.position"),
                _finite(held_raw.get("orientation"), 4, "held.orientation"),
            )
        doors = data.get("open_doors", [])
        if not isinstance(doors, list) or not all(isinstance(d, str) for d in doors):
            raise ValueError("'open_doors' must be a list of door names")
        (offset,) = _finite([data.get("held_yaw_offset", 0.0)], 1, "held_yaw_offset")
        return State(
            poses=tuple(sorted(poses)),
            open_doors=frozenset(doors),
            robot=RobotConf.make(
                _finite(robot_raw.get("base"), 3, "robot.base"),
                _finite([robot_raw.get("lift")], 1, "robot.lift")[0],
                _arm(robot_raw.get("arm")),
            ),
            held=held,
            held_yaw_offset=offset,
        )


def _arm(value: object) -> tuple[float, ...]:
    """A stored arm configuration: 6 or 7 joints, as the arms robot files describe (which
    robot's is for the problem to say)."""
    length = len(value) if isinstance(value, list | tuple) and len(value) == 6 else 7
    return _finite(value, length, "robot.arm")


def _finite(value: object, length: int, where: str) -> tuple[float, ...]:
    """``value`` as ``length`` finite floats, or ValueError naming ``where``."""
    if not isinstance(value, list | tuple) or len(value) != length:
        raise ValueError(f"'{where}' must be a list of {length} numbers")
    numbers = []
    for item in value:
        if isinstance(item, bool) or not isinstance(item, int | float) or not math.isfinite(item):
            raise ValueError(f"'{where}' holds {item!r:.20}, not a finite number")
        numbers.append(float(item))
    return tuple(numbers)
