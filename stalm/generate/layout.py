"""The static scene of a generated problem: a built-in layout or a layout file, read once.

A layout is a problem file without objects and goal: the robot's start, walls, regions with
their standing poses, doors, and optionally the floor. It is validated by the problem
format's own rules (:class:`LayoutSpec`, a :class:`~stalm.world.spec.ProblemSpec` whose
objects and goal may be empty) and reported as the format reports a problem file: one line
naming the file and the field. Its name, description, horizon and budget are not carried: the
generated problem has its own.

One field beyond the problem format, ``trap:``, makes a layout support ``--trap``: P5's walled
counter (``region``, with its ``walls``), which with ``--trap`` replaces the region named
``replaces`` (or is added), and where the grill starts (``grill_on``, a region, at
``grill_at`` in its frame). Both scenes, with and without the trap, must validate.

The built-in layouts (:data:`BUILT_IN`, files beside this module) are ``kitchen-hall``, the
kitchen and hall of P1-P6, whose two hall tables, which stand free, a seed moves by up to
:data:`HALL_SHIFT` along the hall's walls, their standing poses with them; and
``storeroom``, a shop and its storeroom of shelves and counters, as it is. A layout file is
taken as it is too: the seed varies the objects, not the scene.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError

from stalm.errors import StalmError
from stalm.files import MAX_PROBLEM_FILE_BYTES, load_yaml, read_text
from stalm.generate.arrange import Knobs, Slots, capacity
from stalm.world.object_spec import ObjectSpec
from stalm.world.problem_file import parse_problem
from stalm.world.spec import GoalSpec, ProblemSpec, RegionSpec, WallSpec
from stalm.world.spec_values import Name, Vec2

HERE = Path(__file__).parent
BUILT_IN = {"kitchen-hall": HERE / "kitchen_hall.yaml", "storeroom": HERE / "storeroom.yaml"}
"""The layouts ``--layout`` names, and their files."""
LAYOUTS = tuple(BUILT_IN)
SHIFTED_ROOM = {"kitchen-hall": "hall"}
"""The built-in layouts whose free-standing tables a seed moves: the room they stand in."""
CLUTTERED_FRONTS = frozenset({"kitchen-hall"})
"""The layouts whose chains may have clutter in front of them (every problem and suite made
with them so far was made so, and the same seed keeps making the same file); every other
layout keeps each chain's way in clear (:func:`stalm.generate.arrange.arrange`)."""
HALL_SHIFT = 0.6
"""Metres a hall table may move along its wall (x) and away from it (y), each way."""
STATIC_FIELDS = ("robot", "walls", "regions", "doors")
"""The fields of a layout a generated problem carries (and ``floor`` where the layout has one)."""
NOT_CARRIED = ("name", "description", "horizon", "time_budget_s", "optimal_length")


class LayoutSpec(ProblemSpec):
    """A problem file's scene without objects and goal: checked by the same rules."""

    objects: tuple[ObjectSpec, ...] = ()
    goal: tuple[GoalSpec, ...] = ()


class TrapSpec(BaseModel):
    """A layout's ``trap:`` field: P5's walled counter and where the grill starts."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
    replaces: Name | None = None
    region: RegionSpec
    walls: tuple[WallSpec, ...] = ()
    grill_on: Name
    grill_at: Vec2


@dataclass(frozen=True)
class Layout:
    """A validated layout: its static fields as read, and its trap as read (or None)."""

    name: str
    static: dict[str, Any]
    trap: dict[str, Any] | None
    shifted_room: str | None = None
    clear_fronts: bool = True
    """Does a chain's way in stay clear of clutter (see :data:`CLUTTERED_FRONTS`)?"""

    @property
    def walled(self) -> str | None:
        """The trap's walled counter, if the layout has one."""
        return str(self.trap["region"]["name"]) if self.trap else None

    @property
    def grill_start(self) -> tuple[str, tuple[float, float]] | None:
        """Where the trap's grill starts: a region and (u, v) in its frame."""
        if not self.trap:
            return None
        u, v = self.trap["grill_at"]
        return str(self.trap["grill_on"]), (float(u), float(v))

    def regions(self, *, trap: bool) -> list[dict[str, Any]]:
        """The regions, with the walled counter in place with ``trap``."""
        regions = copy.deepcopy(self.static["regions"])
        if trap:
            if not self.trap:
                raise StalmError(
                    f"--trap: layout {self.name} has no walled counter (no 'trap:' field)"
                )
            walled = copy.deepcopy(self.trap["region"])
            replaced = self.trap.get("replaces")
            index = next((i for i, r in enumerate(regions) if r["name"] == replaced), None)
            if index is None:
                regions.append(walled)
            else:
                regions[index] = walled
        return regions

    def capacity(self, knobs: Knobs) -> int:
        """The most movable objects this layout holds for ``knobs`` (see
        :func:`stalm.generate.arrange.capacity`)."""
        grill = self.grill_start[0] if knobs.trap and self.grill_start else None
        regions = self.regions(trap=knobs.trap)
        return capacity(regions, knobs, self.walled, grill, clear_fronts=self.clear_fronts)

    def check_capacity(self, knobs: Knobs) -> None:
        """A StalmError naming the layout and what it holds when ``knobs.objects`` is more."""
        most = self.capacity(knobs)
        if knobs.objects > most:
            trap = ", the trap" if knobs.trap else ""
            raise StalmError(
                f"--objects {knobs.objects}: layout {self.name} holds at most {most} objects "
                f"with {knobs.goals} goals {knobs.occlusion_depth} deep{trap}"
            )


def load_layout(layout: str) -> Layout:
    """The built-in layout named ``layout``, or the layout file at that path."""
    if layout in BUILT_IN:
        made = read_layout(BUILT_IN[layout], layout, SHIFTED_ROOM.get(layout))
        return replace(made, clear_fronts=layout not in CLUTTERED_FRONTS)
    path = Path(layout)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return read_layout(path, path.name)
    raise StalmError(
        f"unknown layout {layout!r} (available: {', '.join(LAYOUTS)}, or a layout file: a "
        "problem file with no objects, ending in .yaml)"
    )


def read_layout(path: Path, name: str, shifted_room: str | None = None) -> Layout:
    """Read and validate a layout file (see the module docstring)."""
    source = str(path)
    data = load_yaml(read_text(path, MAX_PROBLEM_FILE_BYTES, "layout file"), source)
    if not isinstance(data, dict):
        raise StalmError(f"{source}: a layout file must be a mapping of fields")
    for field, what in (("objects", "objects"), ("goal", "goal")):
        if data.get(field):
            raise StalmError(
                f"{source}: a layout has no {what} (it has {len(data[field])}): stalm generate "
                "puts the objects and draws the goal; remove the field"
            )
    trap = data.pop("trap", None)
    static = {k: v for k, v in data.items() if k not in (*NOT_CARRIED, "objects", "goal")}
    parse_problem({"name": "layout", **static}, source, LayoutSpec)
    if trap is not None:
        try:
            TrapSpec.model_validate(trap)
        except ValidationError as error:
            first = error.errors()[0]
            where = ".".join(str(part) for part in ("trap", *first["loc"]))
            raise StalmError(f"{source}: {where}: {first['msg']}") from None
    made = Layout(name, static, trap, shifted_room)
    if trap is not None:
        walls = [*static.get("walls", ()), *trap.get("walls", ())]
        with_trap = {**static, "regions": made.regions(trap=True), "walls": walls}
        parse_problem({"name": "layout", **with_trap}, f"{source} (with its trap)", LayoutSpec)
        if trap["grill_on"] not in {r["name"] for r in with_trap["regions"]}:
            raise StalmError(f"{source}: trap.grill_on: '{trap['grill_on']}' is not a region")
    if not any(Slots.of(region).free for region in static["regions"]):
        raise StalmError(
            f"{source}: no region can hold an object (each usable area is narrower than a "
            "bottle's footprint)"
        )
    return made


def scene(layout: Layout, rng: np.random.Generator, *, door: bool, trap: bool) -> dict[str, Any]:
    """The static parts of a problem file (robot, walls, regions, doors, and the layout's
    floor if it has one) for ``layout``; ``trap`` puts the walled counter in, ``door=False``
    leaves the doorways open."""
    regions = layout.regions(trap=trap)
    walls: list[dict[str, Any]] = copy.deepcopy(list(layout.static.get("walls", ())))
    if trap and layout.trap:
        walls += copy.deepcopy(list(layout.trap.get("walls", ())))
    for region in regions:
        if region["room"] != layout.shifted_room:
            continue
        dx, dy = (float(v) for v in rng.uniform(-HALL_SHIFT, HALL_SHIFT, 2))
        dy *= 0.5  # the two tables face each other across the hall: keep them apart
        region["center"] = [region["center"][0] + dx, region["center"][1] + dy]
        x, y, yaw = region["base_pose"]
        region["base_pose"] = [x + dx, y + dy, yaw]
    static = {
        "robot": copy.deepcopy(layout.static["robot"]),
        "walls": walls,
        "regions": regions,
        "doors": copy.deepcopy(list(layout.static.get("doors", ()))) if door else [],
    }
    if "floor" in layout.static:
        static["floor"] = copy.deepcopy(layout.static["floor"])
    return static
