from __future__ import annotations

import itertools
import math

import numpy as np
import pybullet as p
import pytest

from stalm.geometry.transforms import gripper_rotation, quat_from_matrix
from stalm.motion.arm_motion import (
    MAX_JOINT_STEP,
    MAX_LIFT_STEP,
    interpolate,
    interpolate_waypoints,
    interpolated_length,
)
from stalm.motion.base_motion import BasePath, densified_length, densify
from stalm.motion.ik import solve_ik
from stalm.motion.roadmap import (
    FootprintChecker,
    RoadmapSettings,
    load_or_build_roadmap,
    static_scene_key,
)
from stalm.world.problem import Problem


def test_closed_door_separates_the_rooms_and_open_door_joins_them(domain_factory) -> None:
    domain = domain_factory("P5")
    spec = domain.problem.spec
    start = spec.robot.base
    kitchen = spec.region("counter1").base_pose
    hall = spec.region("counter3").base_pose
    planner = domain.base_planner
    assert planner.route(start, hall, frozenset()) is not None
    assert planner.route(start, kitchen, frozenset()) is None
    assert planner.route(start, kitchen, frozenset({"kitchen_door"})) is not None


def test_roadmap_is_cached_on_disk_by_scene_content(
    problems: dict[str, Problem], domain_factory
) -> None:
    domain = domain_factory("P2")
    settings = RoadmapSettings()
    first = load_or_build_roadmap(domain.sim, frozenset(), settings)
    again = load_or_build_roadmap(domain.sim, frozenset(), settings)
    assert np.array_equal(first.nodes, again.nodes) and first.adjacency == again.adjacency
    # P1 and P2 share walls, regions and doors: the same roadmap key
    assert static_scene_key(problems["P1"].spec, frozenset(), settings) == static_scene_key(
        problems["P2"].spec, frozenset(), settings
    )
    assert static_scene_key(problems["P5"].spec, frozenset(), settings) != static_scene_key(
        problems["P2"].spec, frozenset(), settings
    )


def test_the_footprint_proxy_meets_walls_and_closed_doors_but_not_movable_objects(
    domain_factory,
) -> None:
    domain = domain_factory("P3")
    sim, spec = domain.sim, domain.problem.spec
    sim.set_state(domain.problem.initial_state)
    checker = FootprintChecker(sim, RoadmapSettings())
    start = spec.robot.base[:2]
    door = spec.doors[0]
    doorway = (
        door.hinge[0] + door.width / 2 * math.cos(door.closed_yaw),
        door.hinge[1] + door.width / 2 * math.sin(door.closed_yaw),
    )
    try:
        assert checker.free(*start)
        wall = spec.walls[0]
        assert not checker.free(wall.center[0], wall.center[1])
        # a movable object where the proxy stands changes nothing: the base plans around
        # the static scene, objects are the predicates' business
        can = next(iter(sim.bodies.objects.values()))
        p.resetBasePositionAndOrientation(
            can, [start[0], start[1], 0.5], [0, 0, 0, 1], physicsClientId=sim.client
        )
        assert checker.free(*start)
        sim.set_door(door.name, False)
        closed = checker.free(*doorway)
        sim.set_door(door.name, True)
        opened = checker.free(*doorway)
        assert (closed, opened) == (False, True)
    finally:
        checker.remove()
        sim.set_state(domain.problem.initial_state)


def test_densified_paths_respect_the_resolution() -> None:
    path = BasePath(((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, math.pi / 2)))
    points = densify(path, 0.05)
    assert points[0] == path.corners[0] and points[-1] == path.corners[-1]
    gaps = [math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(points)]
    assert max(gaps) <= 0.05 + 1e-9


def test_arm_interpolation_steps_are_small_enough() -> None:
    start = (0.8, 0.0, -1.0, 0.0, -2.0, 0.0, 1.5, 0.7)
    end = (1.1, 1.0, 0.5, -0.4, -1.0, 0.3, 2.0, 0.0)
    confs = interpolate(start, end)
    assert confs[0] == start and confs[-1] == end
    for a, b in itertools.pairwise(confs):
        assert abs(b[0] - a[0]) <= MAX_LIFT_STEP + 1e-12
        assert max(abs(y - x) for x, y in zip(a[1:], b[1:], strict=True)) <= MAX_JOINT_STEP + 1e-12


@pytest.mark.parametrize(
    "corners",
    [
        ((0.0, 0.0, 0.0),),
        ((1.0, 1.0, 0.0), (1.0, 1.0, 3.0)),
        ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, math.pi / 2)),
        ((-4.5, -4.5, 0.0), (4.5, 4.5, 0.0), (-4.5, 4.5, 1.0), (0.0, 0.0, -3.0)),
    ],
)
def test_a_densified_path_is_counted_before_it_is_made(corners) -> None:
    path = BasePath(corners)
    for resolution in (0.05, 0.6):
        assert densified_length(path, resolution) == len(densify(path, resolution))


def test_a_path_too_far_to_count_counts_as_infinite() -> None:
    path = BasePath(((0.0, 0.0, 0.0), (1e308, -1e308, 0.0)))
    assert densified_length(path, 0.05) == math.inf


def test_an_arm_motion_is_counted_before_it_is_made() -> None:
    waypoints = [
        (0.85, 0.0, -1.7, 0.0, -3.0, 0.0, 1.5, 0.785),
        (0.8, 0.0, -1.7, 0.0, -3.0, 0.0, 1.5, 0.785),
        (0.8, 1.0, 0.5, -0.4, -1.0, 0.3, 2.0, 0.0),
        (0.8, 1.0, 0.5, -0.4, -1.0, 0.3, 2.0, 0.0),
    ]
    for end in range(1, len(waypoints) + 1):
        assert interpolated_length(waypoints[:end]) == len(interpolate_waypoints(waypoints[:end]))


def test_ik_reaches_a_reachable_gripper_pose_and_is_deterministic(domain_factory) -> None:
    domain = domain_factory("P2")
    sim = domain.sim
    sim.set_state(domain.problem.initial_state)
    stand = domain.problem.spec.region("counter1").base_pose
    target = ((-4.5, 0.75, 1.12), quat_from_matrix(gripper_rotation(stand[2], 0.3)))
    first = solve_ik(sim, stand, target, np.random.default_rng(3))
    again = solve_ik(sim, stand, target, np.random.default_rng(3))
    assert first is not None and first == again
    sim.set_arm(stand, first.lift, first.arm)
    assert math.dist(sim.gripper_pose()[0], target[0]) < 0.005
    unreachable = ((-4.45, 0.75, 3.5), target[1])
    assert solve_ik(sim, stand, unreachable, np.random.default_rng(3), attempts=2) is None


def test_a_route_asked_again_is_the_one_found_the_first_time(domain_factory) -> None:
    """Routes are remembered by door setting, ends and banned edges (Concretize asks for the
    same few hundreds of times): each answer is what the roadmap's search gives, a banned edge
    is a different question, and a caller changing a returned route changes nothing kept."""
    domain = domain_factory("P2")
    planner = domain.base_planner
    doors = frozenset({"kitchen_door"})
    start = domain.problem.spec.robot.base
    goal = domain.problem.spec.regions[0].base_pose
    roadmap = planner.roadmap(doors)
    a, b = roadmap.anchor_index(*start[:2]), roadmap.anchor_index(*goal[:2])
    first = planner.route(start, goal, doors)
    assert first is not None and first == roadmap.shortest_path(a, b)
    first.append(-1)
    assert planner.route(start, goal, doors) == roadmap.shortest_path(a, b)
    edge = (first[1], first[0])  # either direction
    detour = planner.route(start, goal, doors, [edge])
    assert detour == roadmap.shortest_path(a, b, [edge]) and detour != first[:-1]
