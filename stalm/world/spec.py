"""Problem files -> typed, validated specs.

A problem file (YAML) describes a scene (walls, regions, doors, movable objects and where
they start), the robot's start pose and the goal. Every field is checked on load; a mistake
raises one :class:`~stalm.errors.StalmError` naming the file, the field path and what is wrong
(``problems/p5.yaml: objects[2].radius: must be greater than 0``).

Coordinates are metres and radians. Floor x, y span ``floor`` (default [-5, 5]^2). A region is
a box standing on the floor (or floating, for a wall shelf) whose top is the placement surface.
An object's start position is given in its region's frame (u forward/away from the robot's
standing pose side along the region's +x, v to the left), so layouts read like the pictures.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from stalm.errors import StalmError
from stalm.geometry.directions import DIRECTIONS

Positive = Annotated[float, Field(gt=0)]
Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]
RGBA = tuple[float, float, float, float]


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class WallSpec(_Spec):
    """A static box obstacle: room walls, the walls around P5's goal counter."""

    name: str
    center: Vec3
    size: tuple[Positive, Positive, Positive]
    yaw: float = 0.0
    color: RGBA = (0.75, 0.75, 0.72, 1.0)


class RegionSpec(_Spec):
    """A placement surface: the top of a box (counter, table, shelf board, fridge shelf).

    ``base_pose`` is the one predefined robot standing pose for the region (paper §4.1,
    assumption 2). Directions left/right/front/behind on this region are judged in the frame
    of that pose: +x away from the robot is ``behind_of``, +y is ``left_of``.
    """

    name: str
    room: str
    center: Vec2
    yaw: float = 0.0
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


class DoorSpec(_Spec):
    """A hinged door panel closing a doorway.

    The panel turns about a vertical axis at ``hinge``; closed it points along
    ``closed_yaw``, open along ``open_yaw``. The handle sits ``handle_offset`` metres from the
    hinge along the panel at ``handle_height``; ``base_poses`` are the standing poses from
    which the robot can pull it (one per side).
    """

    name: str
    hinge: Vec2
    width: Positive
    height: Positive = 2.0
    thickness: Positive = 0.05
    closed_yaw: float
    open_yaw: float
    handle_height: Positive = 1.05
    handle_offset: Positive | None = None
    base_poses: tuple[Vec3, ...] = Field(min_length=1)
    color: RGBA = (0.45, 0.30, 0.18, 1.0)

    @property
    def handle_distance(self) -> float:
        return self.handle_offset if self.handle_offset is not None else self.width - 0.1


ShapeName = Literal["cylinder", "disc", "grill"]


class ObjectSpec(_Spec):
    """A movable object: a primitive shape resting on a region at the start.

    ``cylinder``: cans, salters, bottles (radius, height). ``disc``: a plate (radius, height
    is its thickness). ``grill``: a box body (``size``) with two side handles along its y
    axis, grasped at a handle.
    """

    name: str
    shape: ShapeName
    radius: Positive | None = None
    height: Positive | None = None
    size: tuple[Positive, Positive, Positive] | None = None
    on: str
    at: Vec2 = Field(description="start position (u, v) in the region's frame")
    yaw: float = Field(default=0.0, description="start yaw relative to the region's frame")
    color: RGBA = (0.8, 0.2, 0.2, 1.0)

    @model_validator(mode="after")
    def _dimensions_match_shape(self) -> ObjectSpec:
        if self.shape in ("cylinder", "disc"):
            if self.radius is None or self.height is None:
                raise ValueError(f"a {self.shape} needs 'radius' and 'height'")
            if self.size is not None:
                raise ValueError(f"a {self.shape} takes 'radius' and 'height', not 'size'")
        else:
            if self.size is None:
                raise ValueError("a grill needs 'size' (x, y, z) of its body")
            if self.radius is not None:
                raise ValueError("a grill takes 'size', not 'radius'")
        return self

    @property
    def half_extents(self) -> tuple[float, float, float]:
        """Half extents of the object's bounding box in its own frame (handles included)."""
        if self.shape == "grill":
            assert self.size is not None
            sx, sy, sz = self.size
            return (sx / 2, sy / 2 + GRILL_HANDLE_REACH, sz / 2)
        assert self.radius is not None and self.height is not None
        return (self.radius, self.radius, self.height / 2)


GRILL_HANDLE_REACH = 0.06
"""How far a grill's side handles stick out of its body (m)."""


class RobotSpec(_Spec):
    """Where the robot starts: base pose (x, y, yaw) on the floor."""

    base: Vec3


class GoalSpec(_Spec):
    """One goal conjunct AtPosition(obj, direction, ref)."""

    obj: str
    direction: Literal["on", "left_of", "right_of", "front_of", "behind_of"]
    ref: str


class ProblemSpec(_Spec):
    """A whole problem file."""

    name: str
    description: str = ""
    floor: tuple[Vec2, Vec2] = ((-5.0, -5.0), (5.0, 5.0))
    horizon: int = Field(default=20, gt=0)
    time_budget_s: Positive = 300.0
    walls: tuple[WallSpec, ...] = ()
    regions: tuple[RegionSpec, ...] = Field(min_length=1)
    doors: tuple[DoorSpec, ...] = ()
    objects: tuple[ObjectSpec, ...] = Field(min_length=1)
    robot: RobotSpec
    goal: tuple[GoalSpec, ...] = Field(min_length=1)
    optimal_length: int | None = None

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
                if name in seen:
                    raise ValueError(
                        f"{group}[{index}].name: '{name}' is already used by {seen[name]}"
                    )
                seen[name] = f"{group}[{index}]"
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
            reach = _rotated_half_extent(hx, hy, obj.yaw)
            if abs(obj.at[0]) + reach[0] > ux / 2 + 1e-6 or abs(obj.at[1]) + reach[1] > (
                uy / 2 + 1e-6
            ):
                raise ValueError(
                    f"objects[{index}].at: {obj.at} puts '{obj.name}' outside the usable area "
                    f"{region.usable_size} of '{obj.on}'"
                )
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
        return self

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


def _rotated_half_extent(hx: float, hy: float, yaw: float) -> tuple[float, float]:
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    return (c * hx + s * hy, s * hx + c * hy)


def _format_validation_error(path: str, error: ValidationError) -> str:
    lines = []
    for item in error.errors():
        location = _format_location(item.get("loc", ()))
        message = str(item.get("msg", "invalid")).removeprefix("Value error, ")
        lines.append(f"{path}: {location}: {message}" if location else f"{path}: {message}")
    return "\n".join(lines)


def _format_location(loc: tuple[object, ...]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
    return text


def parse_problem(data: object, source: str = "<problem>") -> ProblemSpec:
    """Validate already-loaded problem data; errors name ``source`` and the field."""
    if not isinstance(data, dict):
        raise StalmError(f"{source}: a problem file must be a mapping of fields, got {data!r:.60}")
    try:
        return ProblemSpec.model_validate(data)
    except ValidationError as error:
        raise StalmError(_format_validation_error(source, error)) from None


def load_problem_file(path: Path) -> ProblemSpec:
    """Read and validate one problem file."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as error:
        raise StalmError(f"{path}: cannot read problem file ({error.strerror})") from None
    except UnicodeDecodeError as error:
        raise StalmError(
            f"{path}: not a problem file (not UTF-8 text: byte {error.object[error.start]:#04x} "
            f"at offset {error.start})"
        ) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise StalmError(f"{path}: not valid YAML: {error}") from None
    return parse_problem(data, str(path))
