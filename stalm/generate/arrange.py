"""Where a generated problem's objects start, what its goal is, and the task plan that solves it.

Objects stand on a grid of slots per region, in the region's frame (``u`` away from the
robot's standing pose, ``v`` to its left; rows :data:`ROW` apart, columns :data:`COLUMN`
apart). A *chain* is a goal object in the back row of a column with ``depth`` occluders in
front of it, in the rows before it, as P3's milk stands behind its bottles: the robot must
move them, front first, before it can reach the goal object. Each goal object goes to a
region in the other room (so a closed door must be opened first); with two goals or more the
last one goes beside a reference object standing there (``left_of``), as P2's salter goes
right of its bottle. With ``trap`` the goal is P5's: cans and then the grill onto the walled
counter, where the grill fits only at the front and, standing there, leaves no room; the
region the grill starts on holds nothing else. The other objects are clutter, on free slots
anywhere but the walled counter; the front half of each goal region and the front rows of the
regions occluders are put on stay free. :func:`capacity` counts, from the regions alone, how
many objects that leaves room for whatever is drawn.

The task plan that solves it (:class:`Arrangement.plan`) follows from the construction: open
the door, then for each chain its occluders onto other regions, front first, then the goal
object to its goal; the trap's grill last. :mod:`stalm.generate.witness` grounds it in the
simulator.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.errors import StalmError
from stalm.generate.clutter_meshes import MESH_SHARE, ClutterMesh

ROW = 0.09
"""Metres between rows of slots (along ``u``): a bottle's diameter and 2 cm."""
COLUMN = 0.11
"""Metres between columns of slots (along ``v``): room for the fingers between two objects."""
EDGE = 0.036
"""Clearance from a slot's centre to the usable area's edge: the largest object's radius."""
CAN = {"shape": "cylinder", "radius": 0.033, "height": 0.12}
BOTTLE = {"shape": "cylinder", "radius": 0.035, "height": 0.25}
GRILL = {"shape": "grill", "size": [0.16, 0.42, 0.45], "handle_height": 0.135}
"""P5's grill: its lid makes it too tall to reach over into the walled pocket behind it."""
DUMP = "?"
"""Stands for an occluder's region in a chain's steps until the regions are known."""
MAX_DEPTH = 3
"""Deepest chain: a counter holds four rows."""
MAX_GOALS = 4
"""Most goal objects of a generated problem."""
MAX_OBJECTS = 1000
"""Most movable objects of any generated problem (``--objects``, each of ``--sizes``), whatever
the layout holds: beyond it a problem takes too long to make and to load."""
GOAL_TOP_MAX = 1.4
"""Regions whose top is higher (the kitchen's shelf, at 1.6 m) are for clutter only: no chain
starts there and no goal or occluder goes there."""
PALETTE = (
    (0.8, 0.15, 0.15, 1.0),
    (0.15, 0.55, 0.2, 1.0),
    (0.2, 0.35, 0.8, 1.0),
    (0.85, 0.65, 0.1, 1.0),
    (0.55, 0.25, 0.6, 1.0),
    (0.1, 0.6, 0.65, 1.0),
    (0.45, 0.28, 0.12, 1.0),
    (0.92, 0.92, 0.92, 1.0),
)


@dataclass(frozen=True)
class Knobs:
    """What ``stalm generate`` is asked for."""

    objects: int
    goals: int = 2
    occlusion_depth: int = 1
    door: bool = True
    trap: bool = False
    clutter: tuple[ClutterMesh, ...] = ()
    """Meshes about half the clutter is drawn from (none: cans and bottles only, drawn as
    before meshes could be, so earlier seeds make the same files)."""

    def __post_init__(self) -> None:
        if not 1 <= self.goals <= MAX_GOALS:
            raise StalmError(f"--goals must be 1 to {MAX_GOALS}, got {self.goals}")
        if not 0 <= self.occlusion_depth <= MAX_DEPTH:
            raise StalmError(
                f"--occlusion-depth must be 0 to {MAX_DEPTH} (a counter holds {MAX_DEPTH + 1} "
                f"rows), got {self.occlusion_depth}"
            )
        if self.trap and not 2 <= self.goals <= 3:
            raise StalmError(
                "--trap puts the grill and one or two cans on the walled counter: --goals must "
                f"be 2 or 3, got {self.goals}"
            )
        if self.objects < self.least_objects:
            raise StalmError(
                f"--objects {self.objects} is too few for {self.goals} goals "
                f"{self.occlusion_depth} deep: at least {self.least_objects}"
            )
        if self.objects > MAX_OBJECTS:  # what a layout holds is checked with the layout
            raise StalmError(f"--objects must be at most {MAX_OBJECTS}, got {self.objects}")

    @property
    def relative(self) -> bool:
        """Does the last goal go beside a reference object?"""
        return self.goals >= 2 and not self.trap

    @property
    def least_objects(self) -> int:
        chains = self.goals - (1 if self.trap else 0)
        return chains * (1 + self.occlusion_depth) + (1 if self.trap else 0) + self.relative


def grid(region: dict[str, Any]) -> tuple[int, int]:
    """Rows and columns of slots on ``region`` (none where its usable area is too small)."""
    ux, uy = region.get("usable") or region["size"]
    return max(0, int((ux - 2 * EDGE) // ROW) + 1), max(0, int((uy - 2 * EDGE) // COLUMN) + 1)


@dataclass
class Slots:
    """A region's free slots, ``(row, column) -> (u, v)``; row 0 is the back row."""

    region: dict[str, Any]
    free: dict[tuple[int, int], tuple[float, float]] = field(default_factory=dict)

    @classmethod
    def of(cls, region: dict[str, Any]) -> Slots:
        ux = (region.get("usable") or region["size"])[0]
        rows, columns = grid(region)
        back = ux / 2 - EDGE
        left = (columns - 1) * COLUMN / 2
        return cls(
            region,
            {
                (r, c): (round(back - r * ROW, 4), round(left - c * COLUMN, 4))
                for r in range(rows)
                for c in range(columns)
            },
        )

    @property
    def rows(self) -> int:
        return 1 + max((r for r, _ in self.free), default=-1)

    def column_free(self, column: int, rows: int) -> bool:
        return all((r, column) in self.free for r in range(rows))

    def take(self, key: tuple[int, int]) -> tuple[float, float]:
        return self.free.pop(key)


@dataclass(frozen=True)
class Arrangement:
    """A generated problem's objects and goal (problem-file fields) and its solving task plan."""

    objects: list[dict[str, Any]]
    goal: list[list[str]]
    plan: tuple[DiscreteAction, ...]
    dumps: tuple[str, ...]
    """Regions an occluder may be put on (no goal goes there, and no chain starts there where
    the scene has such regions), most free room first."""


def clutter_only(region: dict[str, Any]) -> bool:
    """Is ``region`` too high for chains, goals and occluders (see :data:`GOAL_TOP_MAX`)?"""
    return float(region["top"]) > GOAL_TOP_MAX


def capacity(
    regions: list[dict[str, Any]],
    knobs: Knobs,
    walled: str | None,
    grill_region: str | None,
    *,
    clear_fronts: bool = False,
) -> int:
    """The most objects :func:`arrange` always has room for on ``regions`` with ``knobs``,
    whichever regions and columns it draws: every slot, less the slots it keeps free at most
    (each chain's two side columns, and with ``clear_fronts`` its way in, three columns of the
    deepest region; half of each goal region, the largest ones counted; three per occluder
    put down; the walled counter and the grill's region whole), and the grill, which takes no
    slot."""
    sizes = {r["name"]: len(Slots.of(r).free) for r in regions}
    chains = knobs.goals - (1 if knobs.trap else 0)
    apart = {walled, grill_region} if knobs.trap else set()
    held = sum(n for name, n in sizes.items() if name not in apart)
    deepest = max(grid(r)[0] for r in regions)
    chain = knobs.occlusion_depth + 1
    sides = (3 * deepest - chain if clear_fronts else 2 * chain) * chains
    halves = 0
    if not knobs.trap:
        goal_sizes = [sizes[r["name"]] for r in regions if not clutter_only(r)]
        halves = sum(n // 2 for n in sorted(goal_sizes, reverse=True)[:chains])
    put_down = 3 * chains * knobs.occlusion_depth
    return max(0, held - sides - halves - put_down + (1 if knobs.trap else 0))


def arrange(
    regions: list[dict[str, Any]],
    knobs: Knobs,
    rng: np.random.Generator,
    door: str | None,
    walled: str | None = None,
    grill_start: tuple[str, tuple[float, float]] | None = None,
    *,
    clear_fronts: bool = False,
) -> Arrangement:
    """Objects, goal and task plan for ``knobs`` on ``regions`` (see the module docstring);
    ``walled`` is the trap's walled counter and ``grill_start`` the region and slot where the
    grill starts, both needed with ``knobs.trap``. With ``clear_fronts`` no clutter stands in
    front of a chain either (its column and side columns stay free to the region's front), so
    that in dense clutter the way in is as deep as the chain: the kitchen-hall's problems were
    made without it and keep being made so, byte for byte."""
    slots = {r["name"]: Slots.of(r) for r in regions}
    rooms = {r["name"]: r["room"] for r in regions}
    objects: list[dict[str, Any]] = []
    names = _Names()

    def put(kind: dict[str, Any], prefix: str, region: str, at: tuple[float, float]) -> str:
        name = names.next(prefix)
        color = PALETTE[len(objects) % len(PALETTE)]
        objects.append({"name": name, **kind, "on": region, "at": list(at), "color": list(color)})
        return name

    high = {r["name"] for r in regions if clutter_only(r)}
    if walled not in slots:
        walled = None
    grill_region = grill_start[0] if knobs.trap and grill_start else None
    usable = [name for name in slots if name not in high and name not in (walled, grill_region)]
    chains = knobs.goals - (1 if knobs.trap else 0)
    goal: list[list[str]] = []
    steps: list[list[DiscreteAction]] = []
    goal_regions: set[str] = {walled} if knobs.trap and walled else set()
    sources_used: set[str] = set()
    grill = None
    if knobs.trap:
        if walled is None or grill_start is None:
            raise StalmError("the layout has no walled counter for --trap")
        grill = put(GRILL, "grill", grill_start[0], grill_start[1])
        slots[grill_start[0]].free.clear()  # the grill stands at its front; nothing else goes
    for index in range(chains):
        sources = [
            s
            for s in usable
            if s not in goal_regions
            and slots[s].rows > knobs.occlusion_depth
            and any(slots[s].column_free(c, knobs.occlusion_depth + 1) for c in _columns(slots[s]))
        ]
        if not sources:
            raise StalmError(f"no region has room for {chains} chains {knobs.occlusion_depth} deep")
        source = sources[int(rng.integers(len(sources)))]
        columns = [
            c
            for c in _columns(slots[source])
            if slots[source].column_free(c, knobs.occlusion_depth + 1)
        ]
        column = columns[int(rng.integers(len(columns)))]
        target = (
            walled
            if knobs.trap
            else _goal_region(usable, rooms, source, goal_regions, sources_used, rng)
        )
        assert target is not None
        goal_regions.add(target)
        sources_used.add(source)
        obj = put(CAN, "can", source, slots[source].take((0, column)))
        occluders = [
            put(
                BOTTLE if rng.random() < 0.5 else CAN,
                "blocker",
                source,
                slots[source].take((r, column)),
            )
            for r in range(1, knobs.occlusion_depth + 1)
        ]
        # the chain's sides stay clear (with clear_fronts its way in too): only its own
        # occluders stand in the way
        rows = grid(slots[source].region)[0] if clear_fronts else knobs.occlusion_depth + 1
        for row in range(rows):
            for side in (
                (column - 1, column, column + 1) if clear_fronts else (column - 1, column + 1)
            ):
                slots[source].free.pop((row, side), None)
        chain_steps: list[DiscreteAction] = []
        for occluder in reversed(occluders):  # the front one first; its region comes below
            chain_steps += [Pick(occluder), Place(occluder, "on", DUMP)]
        chain_steps.append(Pick(obj))
        if knobs.relative and index == chains - 1:
            ref_slot = _middle_slot(slots[target])
            ref = put(BOTTLE, "reference", target, slots[target].take(ref_slot))
            goal += [[obj, "on", target], [obj, "left_of", ref]]
            chain_steps.append(Place(obj, "left_of", ref))
        else:
            goal.append([obj, "on", target])
            chain_steps.append(Place(obj, "on", target))
        steps.append(chain_steps)
    if grill is not None:
        goal.append([grill, "on", walled or ""])
        steps.append([Pick(grill), Place(grill, "on", walled or "")])
    # occluders go where no goal goes, where no chain starts if there is such a region
    spare = [n for n in slots if n not in goal_regions and n not in high]
    spare = [n for n in spare if n not in sources_used] or spare
    dumps = tuple(sorted(spare, key=lambda n: (-len(slots[n].free), n)))
    if not dumps:
        raise StalmError("no region is left to put occluders on")
    put_down = [dumps[i % len(dumps)] for i in range(chains * knobs.occlusion_depth)]
    # kept free of clutter, front rows first (nothing to reach over): three slots for each
    # occluder put down on a region, the front half of a goal region, all the walled counter
    kept: set[tuple[str, tuple[int, int]]] = set()
    for name, region_slots in slots.items():
        wanted = 3 * put_down.count(name)
        if name in goal_regions:
            wanted = len(region_slots.free) if name == walled else len(region_slots.free) // 2
        front_first = sorted(region_slots.free, key=lambda key: (-key[0], key[1]))
        kept |= {(name, key) for key in front_first[:wanted]}
    for _ in range(knobs.objects - len(objects)):
        open_slots = [
            (name, key)
            for name in sorted(slots)
            for key in sorted(slots[name].free)
            if (name, key) not in kept
        ]
        if not open_slots:
            raise StalmError(f"--objects {knobs.objects}: no room left for more clutter")
        region, key = open_slots[int(rng.integers(len(open_slots)))]
        kind = _clutter_kind(knobs.clutter, rng)
        put(kind, "item", region, slots[region].take(key))
    plan: list[DiscreteAction] = [Open(door)] if door else []
    dump = iter(put_down)
    for chain_steps in steps:
        for step in chain_steps:
            if isinstance(step, Place) and step.ref == DUMP:
                step = Place(step.obj, "on", next(dump))
            plan.append(step)
    return Arrangement(objects, goal, tuple(plan), dumps)


def _clutter_kind(meshes: tuple[ClutterMesh, ...], rng: np.random.Generator) -> dict[str, Any]:
    """A clutter object's shape: a mesh of ``meshes`` (:data:`MESH_SHARE` of the time), else a
    bottle or a can; without meshes the one draw it always was."""
    if meshes and rng.random() < MESH_SHARE:
        return meshes[int(rng.integers(len(meshes)))].kind()
    return BOTTLE if rng.random() < 0.4 else CAN


def _columns(slots: Slots) -> list[int]:
    return sorted({c for _, c in slots.free})


def _middle_slot(slots: Slots) -> tuple[int, int]:
    """The free slot nearest the middle of the region (the first of equals, by key)."""
    if not slots.free:
        raise StalmError(f"no free slot on {slots.region['name']} for the goal's reference")
    return min(slots.free, key=lambda key: (abs(slots.free[key][0]) + abs(slots.free[key][1]), key))


def _goal_region(
    usable: list[str],
    rooms: dict[str, str],
    source: str,
    goals: set[str],
    sources: set[str],
    rng: np.random.Generator,
) -> str:
    """A region that is no goal yet, preferably in the other room than ``source`` and where
    no chain starts (with many goals, another chain's region)."""
    free = [n for n in usable if n != source and n not in goals]
    for choices in (
        [n for n in free if rooms[n] != rooms[source] and n not in sources],
        [n for n in free if n not in sources],
        [n for n in free if rooms[n] != rooms[source]],
        free,
    ):
        if choices:
            return choices[int(rng.integers(len(choices)))]
    raise StalmError("no region left for another goal")


class _Names:
    """can_01, can_02, bottle_01, ... in the order asked for."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}

    def next(self, prefix: str) -> str:
        self.counts[prefix] = self.counts.get(prefix, 0) + 1
        return f"{prefix}_{self.counts[prefix]:02d}"
