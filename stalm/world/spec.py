"""The typed, validated specs of a problem: what a valid problem file says.

A problem file (YAML) describes a scene (walls, regions, doors, movable objects and where
they start), the robot's start pose and the goal. Every field is checked when the spec is
built: types and ranges, unique names, objects inside their region's usable area and not
overlapping, goals naming objects and regions of the right kind. Reading the file and naming
it in errors is :mod:`stalm.world.problem_file`'s job.

Coordinates are metres and radians. Floor x, y span ``floor`` (default [-5, 5]^2). A region is
a box standing on the floor (or floating, for a wall shelf) whose top is the placement surface.
An object's start position is given in its region's frame (u forward/away from the robot's
standing pose side along the region's +x, v to the left), so layouts read like the pictures.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import (
    Field,
    PrivateAttr,
    SerializerFunctionWrapHandler,
    ValidationInfo,
    model_serializer,
    model_validator,
)

from stalm.errors import StalmError
from stalm.geometry.directions import DIRECTIONS
from stalm.geometry.footprints import planar_footprints_overlap, rotated_half_extent
from stalm.world.goal_consistency import goal_contradiction
from stalm.world.mesh_files import PYBULLET_DATA_PREFIX
from stalm.world.object_spec import (
    GRILL_HANDLE_REACH,
    MESH_BASE_CONTEXT,
    ObjectSpec,
)
from stalm.world.spec_values import (
    MAX_FLOOR_SIDE,
    RGBA,
    Coordinate,
    Name,
    Positive,
    SpecModel,
    Vec2,
    Vec3,
)

DEFAULT_ROBOT = "panda"
"""The robot of a problem that names none."""


class WallSpec(SpecModel):
    """A static box obstacle: room walls, the walls around P5's goal counter."""

    name: Name
    center: Vec3
    size: tuple[Positive, Positive, Positive]
    yaw: Coordinate = 0.0
    color: RGBA = (0.75, 0.75, 0.72, 1.0)


class RegionSpec(SpecModel):
    """A placement surface: the top of a box (counter, table, shelf board, fridge shelf).

    ``base_pose`` is the one predefined robot standing pose for the region (paper §4.1,
    assumption 2). Directions left/right/front/behind on this region are judged in the frame
    of that pose: +x away from the robot is ``behind_of``, +y is ``left_of``.
    """

    name: Name
    room: Name
    center: Vec2
    yaw: Coordinate = 0.0
    size: tuple[Positive, Positive] = Field(description="footprint of the box (x, y) in its frame")
    top: Positive = Field(description="height of the placement surface above the floor")
    thickness: Positive | None = Field(
        default=None, description="box thickness below the top; None = down to the floor"
    )
    usable: tuple[Positive, Positive] | None = Field(
        default=None, description="usable area (x, y) centred on the top; None = whole top"
    )
    base_pose: Vec3
    color: RGBA = (0.55, 0.42, 0.30, 1.0)

    @property
    def usable_size(self) -> tuple[float, float]:
        return self.usable if self.usable is not None else self.size

    @model_validator(mode="after")
    def _usable_fits(self) -> RegionSpec:
        ux, uy = self.usable_size
        if ux > self.size[0] + 1e-9 or uy > self.size[1] + 1e-9:
            raise ValueError(f"usable area {self.usable_size} is larger than the top {self.size}")
        return self


class DoorSpec(SpecModel):
    """A hinged door panel closing a doorway.

    The panel turns about a vertical axis at ``hinge``; closed it points along
    ``closed_yaw``, open along ``open_yaw``. The handle sits ``handle_offset`` metres from the
    hinge along the panel at ``handle_height``; ``base_poses`` are the standing poses from
    which the robot can pull it (one per side).
    """

    name: Name
    hinge: Vec2
    width: Positive
    height: Positive = 2.0
    thickness: Positive = 0.05
    closed_yaw: Coordinate
    open_yaw: Coordinate
    handle_height: Positive = 1.05
    handle_offset: Positive | None = None
    base_poses: tuple[Vec3, ...] = Field(min_length=1)
    color: RGBA = (0.45, 0.30, 0.18, 1.0)

    @property
    def handle_distance(self) -> float:
        return self.handle_offset if self.handle_offset is not None else self.width - 0.1


class RobotSpec(SpecModel):
    """Which robot, and where it starts: base pose (x, y, yaw) on the floor.

    ``file`` names a built-in robot (``stalm robot list``) or a robot file, relative to the
    problem file; unset, the Panda on its mobile base, as every problem before robot files."""

    base: Vec3
    file: str | None = Field(default=None, min_length=1, max_length=1024)
    _resolved: str | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _resolve_file(self, info: ValidationInfo) -> RobotSpec:
        if self.file is not None and Path(self.file).suffix in (".yaml", ".yml"):
            context = info.context if isinstance(info.context, dict) else {}
            base = context.get(MESH_BASE_CONTEXT)
            path = Path(self.file).expanduser()
            if not path.is_absolute() and base is not None:
                path = Path(base) / path
            self._resolved = str(path.resolve())  # the robot loads later, maybe elsewhere
        return self

    @model_serializer(mode="wrap")
    def _without_unset_file(self, handler: SerializerFunctionWrapHandler) -> dict[str, object]:
        """No ``file`` when none is named: the Panda's problems are written and hashed as
        before robot files existed."""
        data: dict[str, object] = handler(self)
        if self.file is None:
            data.pop("file", None)
        return data

    @property
    def robot(self) -> str:
        """What :func:`~stalm.world.robot_loader.load_robot` takes: a built-in robot's name
        or a robot file's path (resolved against the problem file's folder)."""
        if self.file is None:
            return DEFAULT_ROBOT
        return self._resolved if self._resolved is not None else self.file


class GoalSpec(SpecModel):
    """One goal conjunct AtPosition(obj, direction, ref)."""

    obj: str
    direction: Literal["on", "left_of", "right_of", "front_of", "behind_of"]
    ref: str


class ProblemSpec(SpecModel):
    """A whole problem file."""

    name: Name
    description: str = ""
    floor: tuple[Vec2, Vec2] = ((-5.0, -5.0), (5.0, 5.0))
    horizon: int = Field(default=20, gt=0)
    time_budget_s: Annotated[float, Field(gt=0)] = 300.0
    walls: tuple[WallSpec, ...] = ()
    regions: tuple[RegionSpec, ...] = Field(min_length=1)
    doors: tuple[DoorSpec, ...] = ()
    objects: tuple[ObjectSpec, ...] = Field(min_length=1)
    robot: RobotSpec
    goal: tuple[GoalSpec, ...] = Field(min_length=1)
    optimal_length: int | None = None
    _files_folder: Path | None = PrivateAttr(default=None)

    @model_validator(mode="before")
    @classmethod
    def _goal_from_lists(cls, data: object) -> object:
        """Accept goals written as ``[obj, direction, ref]`` lists as well as mappings."""
        if isinstance(data, dict) and isinstance(data.get("goal"), list):
            goal = []
            for item in data["goal"]:
                if isinstance(item, list | tuple) and len(item) == 3:
                    goal.append({"obj": item[0], "direction": item[1], "ref": item[2]})
                else:
                    goal.append(item)
            data = {**data, "goal": goal}
        return data

    @model_validator(mode="after")
    def _names_are_consistent(self) -> ProblemSpec:
        seen: dict[str, str] = {}
        groups: tuple[tuple[str, tuple[str, ...]], ...] = (
            ("walls", tuple(w.name for w in self.walls)),
            ("regions", tuple(r.name for r in self.regions)),
            ("doors", tuple(d.name for d in self.doors)),
            ("objects", tuple(o.name for o in self.objects)),
        )
        for group, names in groups:
            for index, name in enumerate(names):
                if name.lower() in seen:  # PDDL does not tell case apart
                    raise ValueError(
                        f"{group}[{index}].name: '{name}' is already used by {seen[name.lower()]}"
                    )
                seen[name.lower()] = f"{group}[{index}]"
        self._check_floor()
        regions = {r.name: r for r in self.regions}
        objects = {o.name for o in self.objects}
        for index, obj in enumerate(self.objects):
            if obj.on not in regions:
                raise ValueError(
                    f"objects[{index}].on: '{obj.on}' is not a region "
                    f"(regions: {', '.join(regions)})"
                )
            region = regions[obj.on]
            ux, uy = region.usable_size
            hx, hy, _ = obj.half_extents
            reach = rotated_half_extent(hx, hy, obj.yaw)
            if abs(obj.at[0]) + reach[0] > ux / 2 + 1e-6 or abs(obj.at[1]) + reach[1] > (
                uy / 2 + 1e-6
            ):
                handles = (
                    f", handles included ({GRILL_HANDLE_REACH:g} m each side)"
                    if obj.shape == "grill"
                    else ""
                )
                raise ValueError(
                    f"objects[{index}].at: {obj.at} puts '{obj.name}' outside the usable area "
                    f"{region.usable_size} of '{obj.on}': its footprint is "
                    f"{2 * reach[0]:.3g} x {2 * reach[1]:.3g} m in the region's frame{handles}, so "
                    f"its centre may be at most ({max(0.0, ux / 2 - reach[0]):.3g}, "
                    f"{max(0.0, uy / 2 - reach[1]):.3g}) from the area's centre"
                )
        self._check_overlaps()
        for index, goal in enumerate(self.goal):
            if goal.obj not in objects:
                raise ValueError(f"goal[{index}].obj: '{goal.obj}' is not a movable object")
            if goal.direction == "on" and goal.ref not in regions:
                raise ValueError(f"goal[{index}].ref: 'on' needs a region, '{goal.ref}' is not one")
            if goal.direction != "on" and goal.ref not in objects:
                raise ValueError(
                    f"goal[{index}].ref: '{goal.direction}' needs a movable object, "
                    f"'{goal.ref}' is not one"
                )
            if goal.ref == goal.obj:
                raise ValueError(f"goal[{index}]: an object cannot be placed relative to itself")
        assert set(DIRECTIONS) >= {g.direction for g in self.goal}
        contradiction = goal_contradiction([(g.obj, g.direction, g.ref) for g in self.goal])
        if contradiction is not None:
            raise ValueError(contradiction)
        return self

    @model_validator(mode="after")
    def _remember_files_folder(self, info: ValidationInfo) -> ProblemSpec:
        """Keep the folder relative file paths were resolved against, for a record of the
        problem to say (a relative path in its embedded copy means nothing elsewhere)."""
        if self._names_relative_files():
            context = info.context if isinstance(info.context, dict) else {}
            base = context.get(MESH_BASE_CONTEXT)
            self._files_folder = Path(base if base is not None else ".").resolve()
        return self

    def _names_relative_files(self) -> bool:
        files = [obj.mesh for obj in self.objects if obj.mesh is not None]
        files = [name for name in files if not name.startswith(PYBULLET_DATA_PREFIX)]
        if self.robot.file is not None and Path(self.robot.file).suffix in (".yaml", ".yml"):
            files.append(self.robot.file)  # a path, not a built-in robot's name
        return any(not Path(name).expanduser().is_absolute() for name in files)

    @property
    def files_folder(self) -> Path | None:
        """The folder (absolute) the problem's relative file paths (its robot file, its
        meshes) resolve against: the problem file's, or the working folder for data parsed
        without one; None if it names no file by a relative path."""
        return self._files_folder

    def _check_floor(self) -> None:
        """The robot's start and every standing pose lie on the floor."""
        (x0, y0), (x1, y1) = self.floor
        if not (x0 < x1 and y0 < y1):
            raise ValueError(f"floor: {self.floor} is not (min corner, max corner)")
        if x1 - x0 > MAX_FLOOR_SIDE or y1 - y0 > MAX_FLOOR_SIDE:
            raise ValueError(
                f"floor: {self.floor} is more than {MAX_FLOOR_SIDE:g} m on a side (the scene "
                "check floods it on a 10 cm grid)"
            )
        poses: list[tuple[str, Vec3]] = [("robot.base", self.robot.base)]
        poses += [(f"regions[{i}].base_pose", r.base_pose) for i, r in enumerate(self.regions)]
        for i, door in enumerate(self.doors):
            poses += [
                (f"doors[{i}].base_poses[{k}]", pose) for k, pose in enumerate(door.base_poses)
            ]
        for where, (x, y, _) in poses:
            if not (x0 < x < x1 and y0 < y < y1):
                raise ValueError(f"{where}: ({x:g}, {y:g}) is off the floor {self.floor}")

    def _check_overlaps(self) -> None:
        """No two objects on one region overlap (their start poses would be contradictory:
        each both in front of and behind the other, the simulator pushing them apart)."""
        by_region: dict[str, list[tuple[int, ObjectSpec]]] = {}
        for index, obj in enumerate(self.objects):
            by_region.setdefault(obj.on, []).append((index, obj))
        for group in by_region.values():
            for n, (i, a) in enumerate(group):
                for j, b in group[n + 1 :]:
                    if _footprints_overlap(a, b):
                        raise ValueError(
                            f"objects[{j}].at: '{b.name}' overlaps '{a.name}' (objects[{i}]) "
                            f"on '{a.on}'"
                        )

    def region(self, name: str) -> RegionSpec:
        for region in self.regions:
            if region.name == name:
                return region
        raise StalmError(f"problem {self.name}: unknown region '{name}'")

    def object(self, name: str) -> ObjectSpec:
        for obj in self.objects:
            if obj.name == name:
                return obj
        raise StalmError(f"problem {self.name}: unknown object '{name}'")

    def door(self, name: str) -> DoorSpec:
        for door in self.doors:
            if door.name == name:
                return door
        raise StalmError(f"problem {self.name}: unknown door '{name}'")

    @property
    def placement_count(self) -> int:
        """n(R) + 4 n(O): the number of possible placements the paper reports per problem."""
        return len(self.regions) + 4 * len(self.objects)


_OVERLAP_SLACK = 1e-6
"""Footprints may touch; they overlap when they share more than this (m)."""


def _footprint(
    obj: ObjectSpec, x: float, y: float, yaw: float
) -> tuple[float, float, float, float, float | None]:
    """(x, y, yaw, half x, half y) of a grill's, a box's or a mesh's rectangle, or (x, y, 0, r,
    None) of a circle, for the object standing at (x, y) with ``yaw`` (in any one planar frame)."""
    if obj.shape in ("grill", "box", "mesh"):
        hx, hy, _ = obj.half_extents
        return (x, y, yaw, hx, hy)
    assert obj.radius is not None
    return (x, y, 0.0, obj.radius, None)


def _footprints_overlap(a: ObjectSpec, b: ObjectSpec) -> bool:
    """Do the 2D footprints of two objects on one region, at their start, overlap?"""
    return footprints_overlap(a, (*a.at, a.yaw), b, (*b.at, b.yaw))


def footprints_overlap(
    a: ObjectSpec,
    at_a: tuple[float, float, float],
    b: ObjectSpec,
    at_b: tuple[float, float, float],
    slack: float = _OVERLAP_SLACK,
) -> bool:
    """Do the 2D footprints of ``a`` at (x, y, yaw) ``at_a`` and ``b`` at ``at_b`` (one planar
    frame) share more than ``slack`` metres?"""
    return planar_footprints_overlap(_footprint(a, *at_a), _footprint(b, *at_b), slack)
