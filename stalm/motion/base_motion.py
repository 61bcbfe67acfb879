"""Base navigation: roadmap routes turned into dense SE(2) paths, checked against the world.

A route between two standing poses comes from the roadmap of the current door setting; the
dense path is then swept with the real robot bodies (base, folded arm, held object) against
everything in the scene. A blocked edge is banned and the route searched again (lazy PRM), so
paths around movable objects are still found; when none is left the blockers are reported.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field

from stalm.geometry.transforms import wrap_angle
from stalm.motion.colliders import Collider, make_collider
from stalm.motion.roadmap import Roadmap, RoadmapSettings, load_or_build_roadmap
from stalm.world.scene import Sim

SE2 = tuple[float, float, float]
MAX_REPLANS = 6

ROUTES_KEPT = 4096
"""How many routes a :class:`BasePlanner` remembers (then it forgets them all and starts
again: a trial asks for a few dozen distinct ones)."""

RouteKey = tuple[frozenset[str], int, int, frozenset[tuple[int, int]]]
"""A route's door setting, start and goal nodes, and banned edges (each as (low, high))."""


@dataclass(frozen=True)
class BasePath:
    """A base path as its roadmap corner points; :func:`densify` gives the checked waypoints."""

    corners: tuple[SE2, ...]

    @property
    def length(self) -> float:
        return sum(
            math.dist(a[:2], b[:2]) for a, b in zip(self.corners, self.corners[1:], strict=False)
        )


@dataclass(frozen=True)
class BasePathResult:
    """A path, or None with the bodies that blocked every route tried."""

    path: BasePath | None
    blockers: frozenset[int] = frozenset()


def densify(path: BasePath, resolution: float) -> list[SE2]:
    """Waypoints at most ``resolution`` apart in position; yaw turns evenly along the way."""
    corners = path.corners
    if len(corners) == 1:
        return [corners[0]]
    total = path.length
    start_yaw, end_yaw = corners[0][2], corners[-1][2]
    turn = wrap_angle(end_yaw - start_yaw)
    points: list[SE2] = [corners[0]]
    travelled = 0.0
    for a, b in itertools.pairwise(corners):
        seg = math.dist(a[:2], b[:2])
        steps = max(1, math.ceil(seg / resolution))
        for i in range(1, steps + 1):
            t = i / steps
            s = travelled + t * seg
            frac = s / total if total > 0 else 1.0
            points.append(
                (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), start_yaw + frac * turn)
            )
        travelled += seg
    if total == 0.0:
        points.append(corners[-1])
    return points


def densified_length(path: BasePath, resolution: float) -> float:
    """``len(densify(path, resolution))``, counted from the corners without making the
    waypoints (infinite when a corner is so far away that the count overflows)."""
    corners = path.corners
    if len(corners) == 1:
        return 1
    count = 1.0
    for a, b in itertools.pairwise(corners):
        steps = math.dist(a[:2], b[:2]) / resolution
        count += max(1, math.ceil(steps)) if math.isfinite(steps) else math.inf
    return count + (1 if path.length == 0.0 else 0)


@dataclass
class BasePlanner:
    """Routes the base between standing poses, one roadmap per door setting."""

    sim: Sim
    settings: RoadmapSettings = field(default_factory=RoadmapSettings)
    resolution: float = 0.05
    engine: str = "batched"
    """How paths are checked against the world (:mod:`stalm.motion.colliders`)."""
    _roadmaps: dict[frozenset[str], Roadmap] = field(default_factory=dict)
    _collider: Collider | None = None
    _routes: dict[RouteKey, tuple[int, ...] | None] = field(default_factory=dict)
    """Routes found, by door setting, ends and banned edges: a roadmap never changes, and
    Concretize's samplers ask for the same few routes hundreds of times in a trial."""

    @property
    def collider(self) -> Collider:
        if self._collider is None:
            self._collider = make_collider(self.sim, self.engine)
        return self._collider

    def roadmap(self, open_doors: frozenset[str]) -> Roadmap:
        if open_doors not in self._roadmaps:
            self._roadmaps[open_doors] = load_or_build_roadmap(self.sim, open_doors, self.settings)
        return self._roadmaps[open_doors]

    def route(
        self,
        start: SE2,
        goal: SE2,
        open_doors: frozenset[str],
        banned: Iterable[tuple[int, int]] = (),
    ) -> list[int] | None:
        roadmap = self.roadmap(open_doors)
        a = roadmap.anchor_index(start[0], start[1])
        b = roadmap.anchor_index(goal[0], goal[1])
        if a is None or b is None:
            raise ValueError(f"base poses {start} / {goal} are not standing poses of this problem")
        banned = frozenset((min(edge), max(edge)) for edge in banned)
        key = (open_doors, a, b, banned)
        if key not in self._routes:
            if len(self._routes) >= ROUTES_KEPT:
                self._routes.clear()
            found = roadmap.shortest_path(a, b, banned)
            self._routes[key] = None if found is None else tuple(found)
        nodes = self._routes[key]
        return None if nodes is None else list(nodes)

    def plan(
        self,
        start: SE2,
        goal: SE2,
        open_doors: frozenset[str],
        ignore: Iterable[int] = (),
        obstacle_filter: frozenset[int] | None = None,
    ) -> BasePathResult:
        """A collision-free path from ``start`` to ``goal`` in the sim's current world.

        The sim's robot must already hold what it carries; ``ignore`` bodies are not obstacles.
        With ``obstacle_filter`` only those bodies count as obstacles.
        """
        if math.dist(start[:2], goal[:2]) < 1e-9:
            path = BasePath((start, goal))
            hits = self.sweep(path, ignore)
            blocking = hits if obstacle_filter is None else hits & obstacle_filter
            return BasePathResult(None, frozenset(blocking)) if blocking else BasePathResult(path)
        roadmap = self.roadmap(open_doors)
        banned: set[tuple[int, int]] = set()
        blockers: set[int] = set()
        for _ in range(MAX_REPLANS):
            nodes = self.route(start, goal, open_doors, banned)
            if nodes is None:
                return BasePathResult(None, frozenset(blockers))
            blocked_edge, hits = self._first_blocked_edge(
                roadmap, nodes, start, goal, ignore, obstacle_filter
            )
            if blocked_edge is None:
                return BasePathResult(self._path_from_nodes(roadmap, nodes, start, goal))
            blockers |= hits
            banned.add(blocked_edge)
        return BasePathResult(None, frozenset(blockers))

    def _path_from_nodes(
        self, roadmap: Roadmap, nodes: list[int], start: SE2, goal: SE2
    ) -> BasePath:
        corners: list[SE2] = [start]
        for node in nodes[1:-1]:
            x, y = roadmap.nodes[node]
            corners.append((float(x), float(y), start[2]))
        corners.append(goal)
        return BasePath(tuple(corners))

    def _first_blocked_edge(
        self,
        roadmap: Roadmap,
        nodes: list[int],
        start: SE2,
        goal: SE2,
        ignore: Iterable[int],
        obstacle_filter: frozenset[int] | None,
    ) -> tuple[tuple[int, int] | None, set[int]]:
        path = self._path_from_nodes(roadmap, nodes, start, goal)
        waypoints_per_edge = _edge_waypoints(path, self.resolution)
        ignored = set(ignore)
        if obstacle_filter is not None:  # only those count: every other body is ignored
            ignored |= set(self.sim.bodies.walls.values()) | set(self.sim.bodies.regions.values())
            ignored |= set(self.sim.bodies.doors.values()) | set(self.sim.bodies.objects.values())
            ignored -= obstacle_filter
        waypoints = [pose for edge in waypoints_per_edge for pose in edge]
        edge_of = [index for index, edge in enumerate(waypoints_per_edge) for _ in edge]
        first, hits = self.collider.route_first_touch(waypoints, ignored)
        if first < 0:
            return None, set()
        a, b = nodes[edge_of[first]], nodes[edge_of[first] + 1]
        return (min(a, b), max(a, b)), hits

    def sweep(self, path: BasePath, ignore: Iterable[int] = ()) -> set[int]:
        """Every body the robot touches anywhere along ``path``."""
        return self.collider.route_touches(densify(path, self.resolution), set(ignore))


def _edge_waypoints(path: BasePath, resolution: float) -> list[list[SE2]]:
    """Dense waypoints grouped by the path edge they lie on."""
    dense = densify(path, resolution)
    corners = path.corners
    groups: list[list[SE2]] = []
    index = 0
    for a, b in itertools.pairwise(corners):
        seg = math.dist(a[:2], b[:2])
        steps = max(1, math.ceil(seg / resolution))
        groups.append(dense[index : index + steps + 1])
        index += steps
    return groups
