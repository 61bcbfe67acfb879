"""The geometric check of a problem file: what loading alone cannot see.

Loading a problem (:mod:`stalm.world.problem_file`, with the field checks of
:mod:`stalm.world.spec`) checks every field cheaply and stays fast. Whether
the scene it describes is possible needs the simulator: an object or the robot starting inside
a wall or another body, a standing pose the robot cannot stand at, or one the base can never
drive to. A planner meeting such a problem fails late and obscurely (no path, no IK, a
"collision" at step 0), so ``stalm solve`` and ``stalm problems --file`` run
:func:`check_problem_geometry` first and name what is at fault.

Reachability is judged on the base roadmap the planners use (with every door open, so the
other room counts as reachable), from the robot's start to every region's and door's standing
pose: a pose the roadmap cannot reach is one no planner here can use.
"""

from __future__ import annotations

from collections import deque

from stalm.errors import StalmError
from stalm.motion.roadmap import Roadmap, RoadmapSettings, load_or_build_roadmap
from stalm.world import robot as robot_model
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
        for index, obj in enumerate(spec.objects):
            hits = sim.contacts_of([sim.bodies.objects[obj.name]])
            if hits:
                faults.append(f"objects[{index}] ('{obj.name}'): starts inside {_names(sim, hits)}")
        hits = sim.robot_contacts()
        if hits:
            faults.append(f"robot.base: the robot starts inside {_names(sim, hits)}")
        for where, pose in _standing_poses(problem):
            sim.set_robot(RobotConf.make(pose, robot_model.CARRY_LIFT, robot_model.CARRY_ARM))
            hits = sim.robot_contacts()
            if hits:
                faults.append(f"{where}: the robot standing there is inside {_names(sim, hits)}")
        if faults:
            return faults
        doors = frozenset(door.name for door in spec.doors)
        roadmap = load_or_build_roadmap(sim, doors, settings or RoadmapSettings())
    start = roadmap.anchor_index(*spec.robot.base[:2])
    reached = _reachable(roadmap, start) if start is not None else set()
    for where, pose in _standing_poses(problem):
        anchor = roadmap.anchor_index(pose[0], pose[1])
        if anchor is None or anchor not in reached:
            faults.append(
                f"{where}: the base cannot drive there from the robot's start "
                "(no roadmap path, even with every door open)"
            )
    return faults


def check_problem_geometry(problem: Problem, settings: RoadmapSettings | None = None) -> None:
    """A StalmError listing every fault of :func:`problem_geometry_faults`, one per line."""
    faults = problem_geometry_faults(problem, settings)
    if faults:
        raise StalmError("\n".join(f"{problem.source}: {fault}" for fault in faults))
