"""A probabilistic roadmap over the floor for the robot's footprint, one per door setting.

Nodes are collision-free (x, y) positions of a footprint proxy (a cylinder covering the base
and the folded arm, :func:`fitted_to` the robot's base); edges are straight segments checked at
:attr:`RoadmapSettings.resolution` against walls, regions and doors. Movable objects are not in
the roadmap: base paths are checked against them when queried (see
:mod:`stalm.motion.base_motion`). Standing poses of regions and doors and the robot's start are
added as anchor nodes, so every query in the domain is between nodes. A roadmap depends only on
the static scene, so it is built once and cached on disk under a hash of that content.

Narrow passages are where a sampled roadmap fails: with a fixed number of nearest neighbours
the nodes beside a wall all linked to nodes on their own side, and a 1.6 m doorway the robot
clears read as a wall (a layout with the doorway at y 2.0-3.6 of P2's divider left every hall
region unreachable with the default seed). So every doorway gets **passage nodes**: at its
middle and on both sides of it along its normal (:func:`passage_points`), so the edges
through it are short ones between nodes that are each other's nearest. Measured on doorways
at six places along P2's divider, eight roadmap seeds each (48 layouts,
``tests/motion/test_roadmap_passages.py`` repeats the default seed): 1 of 48 failed without
them, 0 with them, at the same build time (2.1 s of CPU). PRM*'s growing neighbour count
k(n) = ⌈e (1 + 1/d) ln n⌉ (Karaman and Frazzoli 2011; about 24 here, ``neighbours=None``) also
failed 0 of 48, but built in 8.9 s (2.4 times the edges), so it is an option, not the default.
"""

from __future__ import annotations

import hashlib
import heapq
import json
import math
import os
import warnings
from collections.abc import Callable, Iterable, Sequence
from contextlib import suppress
from dataclasses import asdict, dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np
import pybullet as p

from stalm.cache_dir import stalm_cache_dir
from stalm.errors import StalmWarning
from stalm.world import robot as robot_model
from stalm.world.scene import PENETRATION_TOLERANCE, Sim
from stalm.world.spec import ProblemSpec

ROADMAP_FORMAT = 3
"""Bump when the roadmap construction changes, so stale cache files are not reused."""

PASSAGE_OFFSETS = (0.35, 0.7)
"""Distances (m) of a doorway's passage nodes from its middle, along its normal each way."""


PROXY_CLEARANCE = 0.02  # m: how much wider than the robot's base the roadmap's cylinder is


@dataclass(frozen=True)
class RoadmapSettings:
    """PRM parameters; all are part of the cache key."""

    samples: int = 350
    neighbours: int | None = 10
    """Nearest neighbours each node tries to link to; None: PRM*'s k(n) (module docstring)."""
    passage_nodes: bool = True
    """Add nodes in and beside every doorway (module docstring)."""
    max_edge: float = 2.5
    resolution: float = 0.05
    proxy_radius: float = robot_model.BASE_RADIUS + PROXY_CLEARANCE
    proxy_height: float = 1.45
    seed: int = 0


@dataclass(frozen=True)
class Roadmap:
    """Nodes (N x 2), undirected edges as an adjacency list, and named anchor nodes."""

    nodes: np.ndarray
    adjacency: tuple[tuple[int, ...], ...]
    anchors: tuple[tuple[float, float], ...]
    open_doors: frozenset[str]

    def anchor_index(self, x: float, y: float) -> int | None:
        """Node index of an anchor at (x, y), if (x, y) is one."""
        for index, (ax, ay) in enumerate(self.anchors):
            if abs(ax - x) < 1e-6 and abs(ay - y) < 1e-6:
                return index
        return None

    def edge_length(self, a: int, b: int) -> float:
        return float(np.linalg.norm(self.nodes[a] - self.nodes[b]))

    @cached_property
    def _lengths(self) -> tuple[tuple[float, ...], ...]:
        """Each node's edge lengths, in :attr:`adjacency`'s order (computed on first use)."""
        return tuple(
            tuple(self.edge_length(node, nxt) for nxt in neighbours)
            for node, neighbours in enumerate(self.adjacency)
        )

    def shortest_path(
        self, start: int, goal: int, blocked: Iterable[tuple[int, int]] = ()
    ) -> list[int] | None:
        """A* over the roadmap avoiding ``blocked`` edges (either direction)."""
        banned = {tuple(sorted(edge)) for edge in blocked}
        goal_xy = self.nodes[goal]
        frontier: list[tuple[float, float, int]] = [(0.0, 0.0, start)]
        came_from: dict[int, int] = {}
        cost = {start: 0.0}
        while frontier:
            _, so_far, node = heapq.heappop(frontier)
            if node == goal:
                path = [node]
                while node in came_from:
                    node = came_from[node]
                    path.append(node)
                return path[::-1]
            if so_far > cost.get(node, math.inf):
                continue
            for nxt, length in zip(self.adjacency[node], self._lengths[node], strict=True):
                if (min(node, nxt), max(node, nxt)) in banned:
                    continue
                new_cost = so_far + length
                if new_cost < cost.get(nxt, math.inf) - 1e-12:
                    cost[nxt] = new_cost
                    came_from[nxt] = node
                    heuristic = float(np.linalg.norm(self.nodes[nxt] - goal_xy))
                    heapq.heappush(frontier, (new_cost + heuristic, new_cost, nxt))
        return None


def anchor_poses(problem: ProblemSpec) -> list[tuple[float, float, float]]:
    """Every pose the robot stands at: its start and each region's and door's standing pose."""
    poses = [problem.robot.base]
    poses.extend(region.base_pose for region in problem.regions)
    for door in problem.doors:
        poses.extend(door.base_poses)
    return [tuple(pose) for pose in poses]  # type: ignore[misc]


def prm_star_neighbours(nodes: int, dimension: int = 2) -> int:
    """PRM*'s neighbour count k(n) = ⌈e (1 + 1/d) ln n⌉ for ``nodes`` nodes in ``dimension``."""
    return max(1, math.ceil(math.e * (1.0 + 1.0 / dimension) * math.log(max(nodes, 2))))


def passage_points(problem: ProblemSpec) -> list[tuple[float, float]]:
    """Points in every doorway and on both sides of it, along the doorway's normal.

    A door's doorway is the span its closed panel covers: from the hinge along ``closed_yaw``
    for ``width``. The points are candidates: each becomes a node only where the footprint is
    free in the roadmap's door setting (a closed panel fills the middle one)."""
    points: list[tuple[float, float]] = []
    for door in problem.doors:
        along = (math.cos(door.closed_yaw), math.sin(door.closed_yaw))
        normal = (-along[1], along[0])
        mx = door.hinge[0] + along[0] * door.width / 2
        my = door.hinge[1] + along[1] * door.width / 2
        points.append((mx, my))
        for offset in PASSAGE_OFFSETS:
            for side in (1.0, -1.0):
                points.append((mx + side * offset * normal[0], my + side * offset * normal[1]))
    return points


def static_scene_key(
    problem: ProblemSpec, open_doors: frozenset[str], settings: RoadmapSettings
) -> str:
    """Content hash of everything a roadmap depends on."""
    content = {
        "format": ROADMAP_FORMAT,
        "floor": problem.floor,
        "walls": [w.model_dump() for w in problem.walls],
        "regions": [r.model_dump() for r in problem.regions],
        "doors": [d.model_dump() for d in problem.doors],
        "anchors": anchor_poses(problem),
        "open_doors": sorted(open_doors),
        "settings": asdict(settings),
    }
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:24]


def cache_dir() -> Path:
    """Where roadmaps (and other derived data) are cached: ``$STALM_CACHE_DIR`` or ~/.cache."""
    return stalm_cache_dir() / "roadmaps"


class FootprintChecker:
    """Collision checks of the footprint proxy against the static scene (and doors).

    Each query tests the proxy against the static bodies only, pair by pair, instead of a
    whole-world collision detection: the movable objects are ignored anyway, and wherever
    they happen to sit while a roadmap is built (all at one spot right after the scene is
    made) a whole-world query paid for every contact among them, 10 times the proxy's own
    cost on P3's twelve cans.
    """

    def __init__(self, sim: Sim, settings: RoadmapSettings) -> None:
        self.sim = sim
        c = sim.client
        col = p.createCollisionShape(
            p.GEOM_CYLINDER,
            radius=settings.proxy_radius,
            height=settings.proxy_height,
            collisionFramePosition=[0, 0, settings.proxy_height / 2 + 0.01],
            physicsClientId=c,
        )
        self.body = int(p.createMultiBody(1.0, col, -1, [0, 0, -50.0], physicsClientId=c))
        bodies = sim.bodies
        self._static = [
            body
            for group in (bodies.walls, bodies.regions, bodies.doors)
            for body in group.values()
        ] + ([bodies.floor] if bodies.floor >= 0 else [])

    def free(self, x: float, y: float) -> bool:
        return not self.hits(x, y, first=True)

    def hits(self, x: float, y: float, *, first: bool = False) -> set[int]:
        """The static bodies and doors the footprint at (x, y) penetrates (with ``first``,
        at most the first one found)."""
        c = self.sim.client
        p.resetBasePositionAndOrientation(self.body, [x, y, 0.0], [0, 0, 0, 1], physicsClientId=c)
        self.sim.collision_checks += 1
        found: set[int] = set()
        for other in self._static:
            points = p.getClosestPoints(self.body, other, 0.0, physicsClientId=c)
            if any(point[8] < -PENETRATION_TOLERANCE for point in points):
                found.add(other)
                if first:
                    break
        return found

    def segment_free(self, a: Sequence[float], b: Sequence[float], resolution: float) -> bool:
        length = math.dist(a, b)
        steps = max(1, math.ceil(length / resolution))
        for i in range(1, steps):
            t = i / steps
            if not self.free(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])):
                return False
        return True

    def remove(self) -> None:
        p.removeBody(self.body, physicsClientId=self.sim.client)


def build_roadmap(
    sim: Sim,
    open_doors: frozenset[str],
    settings: RoadmapSettings,
    progress: Callable[[str], None] | None = None,
) -> Roadmap:
    """Sample and connect a roadmap with the doors in ``open_doors`` open, the rest closed."""
    problem = sim.problem
    doors_before = {door.name: sim.door_is_open(door.name) for door in problem.doors}
    for door in problem.doors:
        sim.set_door(door.name, door.name in open_doors)
    checker = FootprintChecker(sim, settings)
    try:
        rng = np.random.default_rng(settings.seed)
        (x0, y0), (x1, y1) = problem.floor
        margin = settings.proxy_radius
        anchors = [(pose[0], pose[1]) for pose in anchor_poses(problem)]
        unique_anchors: list[tuple[float, float]] = []
        for anchor in anchors:
            if anchor not in unique_anchors:
                unique_anchors.append(anchor)
        points: list[tuple[float, float]] = list(unique_anchors)
        if settings.passage_nodes:
            points += [
                xy for xy in passage_points(problem) if xy not in points and checker.free(*xy)
            ]
        seeded = len(points)
        attempts = 0
        while len(points) < seeded + settings.samples and attempts < settings.samples * 20:
            attempts += 1
            x = float(rng.uniform(x0 + margin, x1 - margin))
            y = float(rng.uniform(y0 + margin, y1 - margin))
            if checker.free(x, y):
                points.append((x, y))
        nodes = np.array(points, dtype=float)
        neighbours = settings.neighbours or prm_star_neighbours(len(points))
        adjacency: list[set[int]] = [set() for _ in points]
        for i in range(len(points)):
            distances = np.linalg.norm(nodes - nodes[i], axis=1)
            order = np.argsort(distances, kind="stable")
            connected = 0
            for j in order[1:]:
                if connected >= neighbours or distances[j] > settings.max_edge:
                    break
                j = int(j)
                if j in adjacency[i]:
                    connected += 1
                    continue
                if checker.segment_free(points[i], points[j], settings.resolution):
                    adjacency[i].add(j)
                    adjacency[j].add(i)
                    connected += 1
        if progress:
            progress(f"roadmap: {len(points)} nodes, {sum(len(a) for a in adjacency) // 2} edges")
        return Roadmap(
            nodes=nodes,
            adjacency=tuple(tuple(sorted(a)) for a in adjacency),
            anchors=tuple(unique_anchors),
            open_doors=open_doors,
        )
    finally:
        checker.remove()
        for name, was_open in doors_before.items():
            sim.set_door(name, was_open)


def _read_cached_roadmap(path: Path, open_doors: frozenset[str]) -> Roadmap | None:
    """The roadmap in a cache file, or None if the file is damaged in any way.

    A cache file is ours but the disk is not: a kill mid-write elsewhere, a full disk or a
    stray copy can leave a truncated or foreign file. Whatever fails to read (a bad zip, a
    missing array, a wrong shape, an edge naming a node that is not there) means "rebuild",
    so every exception is caught here, and only here.
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            nodes = np.asarray(data["nodes"], dtype=float)
            edges = np.asarray(data["edges"])
            anchors = np.asarray(data["anchors"], dtype=float)
        if nodes.ndim != 2 or nodes.shape[1] != 2 or not np.isfinite(nodes).all():
            return None
        if edges.size and (edges.ndim != 2 or edges.shape[1] != 2):
            return None
        if edges.size and (edges.min() < 0 or edges.max() >= len(nodes)):
            return None
        if anchors.size and (anchors.ndim != 2 or anchors.shape[1] != 2):
            return None
        adjacency: list[list[int]] = [[] for _ in range(len(nodes))]
        for a, b in edges.reshape(-1, 2):
            adjacency[int(a)].append(int(b))
            adjacency[int(b)].append(int(a))
        return Roadmap(
            nodes=nodes,
            adjacency=tuple(tuple(sorted(a)) for a in adjacency),
            anchors=tuple((float(x), float(y)) for x, y in anchors.reshape(-1, 2)),
            open_doors=open_doors,
        )
    except Exception:  # any damage means rebuild (see the docstring)
        return None


def fitted_to(settings: RoadmapSettings, sim: Sim) -> RoadmapSettings:
    """``settings`` with a proxy at least ``sim``'s robot's base plus the clearance wide."""
    radius = sim.robot.platform.base_radius + PROXY_CLEARANCE
    return settings if settings.proxy_radius >= radius else replace(settings, proxy_radius=radius)


def load_or_build_roadmap(
    sim: Sim, open_doors: frozenset[str], settings: RoadmapSettings
) -> Roadmap:
    """The roadmap for this static scene and door setting, from the disk cache if present."""
    settings = fitted_to(settings, sim)
    key = static_scene_key(sim.problem, open_doors, settings)
    path = cache_dir() / f"{key}.npz"
    if path.exists():
        cached = _read_cached_roadmap(path, open_doors)
        if cached is not None:
            return cached
    roadmap = build_roadmap(sim, open_doors, settings)
    _store(path, roadmap)
    return roadmap


_UNCACHEABLE: set[Path] = set()
"""Cache folders found unwritable in this process: warned about once, never tried again."""


def _store(path: Path, roadmap: Roadmap) -> None:
    """Keep ``roadmap`` at ``path`` for later runs, if the cache folder can be written.

    A cache is a saving, not a need: when ``$STALM_CACHE_DIR`` is a file or a folder the user
    may not write, the roadmap stays in memory and the run goes on, with one warning per folder
    (a worker process warns once for itself) rather than a traceback."""
    folder = path.parent
    if folder in _UNCACHEABLE:
        return
    edges = np.array(
        [(i, j) for i, nbrs in enumerate(roadmap.adjacency) for j in nbrs if i < j], dtype=np.int64
    ).reshape(-1, 2)
    tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        try:
            np.savez(tmp, nodes=roadmap.nodes, edges=edges, anchors=np.array(roadmap.anchors))
            os.replace(tmp, path)
        finally:
            with suppress(OSError):
                tmp.unlink(missing_ok=True)
    except OSError as error:
        _UNCACHEABLE.add(folder)
        warnings.warn(
            f"cannot cache roadmaps in {folder} ({error.strerror or error}); they are built "
            "anew in every run (set STALM_CACHE_DIR to a folder you may write)",
            StalmWarning,
            stacklevel=3,
        )
