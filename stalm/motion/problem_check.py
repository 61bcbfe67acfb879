"""The geometric check of a problem file: what loading alone cannot see.

Loading a problem (:mod:`stalm.world.problem_file`, with the field checks of
:mod:`stalm.world.spec`) checks every field cheaply and stays fast. Whether
the scene it describes is possible needs the simulator: a region standing inside a wall, an
object or the robot starting inside a wall or another body, two doors passing through each
other (on one hinge, or swinging into each other), a standing pose the robot cannot stand at,
or one the base can never drive to. A planner meeting such a problem fails late and
obscurely (no path, no IK, a "collision" at step 0), so ``stalm solve`` and
``stalm problems --file`` run :func:`check_problem_geometry` first and name what is at fault.

Reachability is judged on the base roadmap the planners use (with every door open, so the
other room counts as reachable), from the robot's start to every region's and door's standing
pose: a pose the roadmap cannot reach is one no planner here can use. Such a fault says why
(:func:`why_unreachable`): a doorway narrower than the robot, the bodies that wall the pose
off from the start (found by flooding the floor on a grid with the robot's footprint), or, if
the floor does connect them, that the roadmap missed a passage.
"""

from __future__ import annotations

import math
from collections import deque

from stalm.errors import StalmError
from stalm.motion.roadmap import (
    FootprintChecker,
    Roadmap,
    RoadmapSettings,
    fitted_to,
    load_or_build_roadmap,
)
from stalm.world.problem import Problem
from stalm.world.scene import Sim
from stalm.world.state import RobotConf


def _names(sim: Sim, bodies: set[int]) -> str:
    return ", ".join(f"'{name}'" for name in sorted(sim.bodies.name_of(b) for b in bodies))


def _standing_poses(problem: Problem) -> list[tuple[str, tuple[float, float, float]]]:
    """Every standing pose with the field that holds it and whose it is."""
    spec = problem.spec
    poses = [
        (f"regions[{i}].base_pose ('{region.name}')", region.base_pose)
        for i, region in enumerate(spec.regions)
    ]
    for i, door in enumerate(spec.doors):
        poses += [
            (f"doors[{i}].base_poses[{k}] ('{door.name}')", pose)
            for k, pose in enumerate(door.base_poses)
        ]
    return poses


def _reachable(roadmap: Roadmap, start: int) -> set[int]:
    seen = {start}
    queue = deque([start])
    while queue:
        for nxt in roadmap.adjacency[queue.popleft()]:
            if nxt not in seen:
                seen.add(nxt)
                queue.append(nxt)
    return seen


def problem_geometry_faults(problem: Problem, settings: RoadmapSettings | None = None) -> list[str]:
    """What is geometrically wrong with ``problem``, one line per fault naming the field.

    Collisions of the initial scene come first; reachability (which may build a roadmap) is
    judged only when the scene itself is sound.
    """
    spec = problem.spec
    faults: list[str] = []
    with Sim(spec) as sim:
        sim.set_state(problem.initial_state)
        walls = set(sim.bodies.walls.values())
        for index, region in enumerate(spec.regions):
            body = sim.bodies.regions[region.name]
            hits = {wall for wall in walls if sim.touches([body], wall)}
            if hits:
                faults.append(
                    f"regions[{index}] ('{region.name}'): stands inside {_names(sim, hits)}"
                )
        for index, obj in enumerate(spec.objects):
            hits = sim.contacts_of([sim.bodies.objects[obj.name]])
            if hits:
                faults.append(f"objects[{index}] ('{obj.name}'): starts inside {_names(sim, hits)}")
        hits = sim.robot_contacts()
        if hits:
            faults.append(f"robot.base: the robot starts inside {_names(sim, hits)}")
        faults += _overlapping_doors(sim)
        for door in spec.doors:  # as the problem starts (the robot stays where it was)
            sim.set_door(door.name, problem.initial_state.is_open(door.name))
        for where, pose in _standing_poses(problem):
            carry = sim.robot.carry_conf
            sim.set_robot(RobotConf.make(pose, carry[0], carry[1:]))
            hits = sim.robot_contacts()
            if hits:
                faults.append(f"{where}: the robot standing there is inside {_names(sim, hits)}")
        if faults:
            return faults
        doors = frozenset(door.name for door in spec.doors)
        settings = fitted_to(settings or RoadmapSettings(), sim)
        roadmap = load_or_build_roadmap(sim, doors, settings)
        start = roadmap.anchor_index(*spec.robot.base[:2])
        reached = _reachable(roadmap, start) if start is not None else set()
        unreachable = [
            (where, pose)
            for where, pose in _standing_poses(problem)
            if roadmap.anchor_index(pose[0], pose[1]) not in reached
        ]
        if unreachable:
            flood = FloorFlood(sim, settings)
            for where, pose in unreachable:
                faults.append(
                    f"{where}: the base cannot drive there from the robot's start, even with "
                    f"every door open: {flood.why_unreachable(pose)}"
                )
    return faults


DOOR_SETTINGS = ((False, False), (True, True), (False, True), (True, False))
"""Both doors of a pair closed, both open, and each open with the other closed."""


def _overlapping_doors(sim: Sim) -> list[str]:
    """A fault per pair of doors whose panels pass through each other, closed or open (two
    doors on one hinge, or swinging into each other): a state the problem can reach would
    have one body inside another. Leaves the doors as it last set them: the caller sets them
    back."""
    doors = sim.problem.doors
    faults = []
    for j, later in enumerate(doors):
        for i, earlier in enumerate(doors[:j]):
            for earlier_open, later_open in DOOR_SETTINGS:
                sim.set_door(earlier.name, earlier_open)
                sim.set_door(later.name, later_open)
                if sim.touches([sim.bodies.doors[later.name]], sim.bodies.doors[earlier.name]):
                    faults.append(
                        f"doors[{j}] ('{later.name}'): its panel {_setting(later_open)} passes "
                        f"through doors[{i}] ('{earlier.name}') {_setting(earlier_open)}"
                    )
                    break
    return faults


def _setting(is_open: bool) -> str:
    return "open" if is_open else "closed"


GRID = 0.1
"""Cell size (m) of the floor flood that explains an unreachable pose."""


class FloorFlood:
    """The floor cells the robot's footprint can stand on, flooded from the robot's start
    with every door open: what separates a standing pose from the start."""

    def __init__(self, sim: Sim, settings: RoadmapSettings) -> None:
        self.sim = sim
        self.settings = settings
        spec = sim.problem
        for door in spec.doors:
            sim.set_door(door.name, True)
        checker = FootprintChecker(sim, settings)
        try:
            (x0, y0), (x1, y1) = spec.floor
            self.origin = (x0, y0)
            self.shape = (max(1, math.ceil((x1 - x0) / GRID)), max(1, math.ceil((y1 - y0) / GRID)))
            self.blocked: dict[tuple[int, int], set[int]] = {}
            for i in range(self.shape[0]):
                for j in range(self.shape[1]):
                    hits = checker.hits(*self.centre((i, j)))
                    if hits:
                        self.blocked[(i, j)] = hits
        finally:
            checker.remove()
        self.start = self._flood(self.cell(spec.robot.base[:2]))

    def centre(self, cell: tuple[int, int]) -> tuple[float, float]:
        return (self.origin[0] + (cell[0] + 0.5) * GRID, self.origin[1] + (cell[1] + 0.5) * GRID)

    def cell(self, xy: tuple[float, ...]) -> tuple[int, int]:
        i = min(self.shape[0] - 1, max(0, int((xy[0] - self.origin[0]) / GRID)))
        j = min(self.shape[1] - 1, max(0, int((xy[1] - self.origin[1]) / GRID)))
        return (i, j)

    def _neighbours(self, cell: tuple[int, int]) -> list[tuple[int, int]]:
        i, j = cell
        return [
            (a, b)
            for a, b in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1))
            if 0 <= a < self.shape[0] and 0 <= b < self.shape[1]
        ]

    def _flood(self, seed: tuple[int, int]) -> set[tuple[int, int]]:
        """The free cells connected to ``seed`` (the nearest free one if it is blocked)."""
        if seed in self.blocked:
            free = [c for c in self._neighbours(seed) if c not in self.blocked]
            if not free:
                return set()
            seed = free[0]
        seen = {seed}
        queue = deque([seed])
        while queue:
            for nxt in self._neighbours(queue.popleft()):
                if nxt not in seen and nxt not in self.blocked:
                    seen.add(nxt)
                    queue.append(nxt)
        return seen

    def _bounding(self, component: set[tuple[int, int]]) -> set[int]:
        """The bodies the footprint hits just outside ``component``: what bounds it."""
        bodies: set[int] = set()
        for cell in component:
            for nxt in self._neighbours(cell):
                bodies |= self.blocked.get(nxt, set())
        return bodies

    def why_unreachable(self, pose: tuple[float, float, float]) -> str:
        """Why the roadmap has no route from the start to ``pose``, in words."""
        narrow = [
            door for door in self.sim.problem.doors if door.width < 2 * self.settings.proxy_radius
        ]
        goal = self._flood(self.cell(pose))
        if goal & self.start:
            where = ", ".join(f"{v:.2f}" for v in pose[:2])
            return (
                "the floor joins them but the base roadmap found no route (a passage too "
                f"narrow for its samples on the way to ({where}); try more roadmap samples)"
            )
        if narrow:
            return "; ".join(
                f"the doorway of '{door.name}' is {door.width:.2f} m wide, narrower than the "
                f"robot ({2 * self.settings.proxy_radius:.2f} m)"
                for door in narrow
            )
        separating = self._bounding(self.start) & self._bounding(goal)
        if not separating:
            return "no floor the robot fits on joins it to the start"
        return f"walled off from the start by {_names(self.sim, separating)}"


def check_problem_geometry(problem: Problem, settings: RoadmapSettings | None = None) -> None:
    """A StalmError listing every fault of :func:`problem_geometry_faults`, one per line."""
    faults = problem_geometry_faults(problem, settings)
    if faults:
        raise StalmError("\n".join(f"{problem.source}: {fault}" for fault in faults))
