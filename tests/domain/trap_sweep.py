"""An exhaustive search for a can placement on a walled counter with the grill at its front.

It asks what every PLACE could draw, not what one sampler call did: the grill at each of its
contact-free poses on the counter (a grid over the usable area, at the counter's yaw: the
only yaw PLACE keeps for it), and a can held at each grasp of a grid over the full pitch and
yaw ranges of PICK, put down at each point of a grid over the counter's usable area, with
the arm at every lift height of a grid over the lift's range and IK seeded at the nominal arm
and a random one. Each candidate is checked by the very test PLACE makes
(:meth:`~stalm.domain.samplers.Samplers._place_motion_free`), in the engine asked for.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from stalm.domain.actions import Place
from stalm.domain.mdp import Domain
from stalm.domain.samplers import Failures, SamplerSettings
from stalm.geometry.transforms import (
    gripper_rotation,
    invert,
    quat_from_matrix,
    se2_to_world,
)
from stalm.motion.arm_model import PANDA_NOMINAL_ARM as NOMINAL_ARM
from stalm.motion.grasps import (
    APPROACH_DISTANCE,
    PITCH_RANGE,
    PLACE_CLEARANCE,
    YAW_RANGE,
    placement_bounds,
)
from stalm.motion.ik import refine
from stalm.motion.manipulation import ArmMotion, placing_hand
from stalm.motion.reach import leave_waypoints, reach_waypoints, solution_conf
from stalm.world import robot as robot_model
from stalm.world.object_spec import ObjectSpec
from stalm.world.problem import Problem
from stalm.world.state import Grasp, ObjectPose, RobotConf, State


@dataclass(frozen=True)
class Grid:
    """How finely the sweep samples each dimension."""

    grill_u: int = 21
    grill_v: int = 5
    placements: int = 6
    pitches: int = 4
    yaws: int = 7
    lift_step: float = 0.1
    random_seeds: int = 1
    pitch_range: tuple[float, float] = PITCH_RANGE
    yaw_range: tuple[float, float] = YAW_RANGE


@dataclass(frozen=True)
class FeasiblePlacement:
    grill: tuple[float, float]
    pitch: float
    yaw: float
    can: tuple[float, float]
    lift: float


@dataclass(frozen=True)
class SweepResult:
    grill_poses: int
    checked_motions: int
    feasible: tuple[FeasiblePlacement, ...]


def side_grasp(obj: ObjectSpec, pitch: float, yaw: float) -> Grasp:
    """The grasp PICK takes of an upright can at ``pitch`` and ``yaw`` (relative to the
    stand), with the can's yaw that of the stand."""
    assert obj.height is not None
    point = (0.0, 0.0, min(obj.height / 2, 0.09))
    gripper = (point, quat_from_matrix(gripper_rotation(yaw, pitch)))
    grasp = invert(gripper)
    return Grasp.make(obj.name, grasp[0], grasp[1])


def _grid(half: float, count: int) -> np.ndarray:
    return np.linspace(-half, half, count) if half > 1e-9 else np.zeros(1)


def sweep_can_placements(
    problem: Problem,
    counter: str,
    can: str,
    engine: str,
    grid: Grid = Grid(),
    stop_at_first: bool = False,
) -> SweepResult:
    """Every feasible placement of ``can`` on ``counter`` with the grill standing on it."""
    domain = Domain.create(problem, sampler_settings=SamplerSettings(engine=engine))  # type: ignore[arg-type]
    try:
        return _sweep(domain, counter, can, grid, stop_at_first)
    finally:
        domain.close()


def _sweep(domain: Domain, counter: str, can: str, grid: Grid, stop_at_first: bool) -> SweepResult:
    spec = domain.problem.spec
    sim = domain.sim
    region = spec.region(counter)
    stand = region.base_pose
    frame = (*region.center, region.yaw)
    start = domain.problem.initial_state
    others = {name: pose for name, pose in start.poses if name not in ("beef_grill", can)}
    robot = {sim.bodies.base, sim.bodies.arm}
    grill_bounds = placement_bounds(spec.object("beef_grill"), region, region.yaw)
    assert grill_bounds is not None, "the grill does not fit on the counter at all"
    grill_poses = []
    for u, v in itertools.product(
        _grid(grill_bounds[0], grid.grill_u), _grid(grill_bounds[1], grid.grill_v)
    ):
        pose = ObjectPose.make(*se2_to_world(frame, u, v), region.top, region.yaw)
        sim.set_state(start)
        sim.place_object("beef_grill", pose)
        if not sim.contacts_of([sim.bodies.objects["beef_grill"]], robot):
            grill_poses.append(((float(u), float(v)), pose))
    can_spec = spec.object(can)
    can_bounds = placement_bounds(can_spec, region, stand[2])
    assert can_bounds is not None
    rng = np.random.default_rng(0)
    lows, highs = zip(*robot_model.ARM_JOINT_LIMITS, strict=True)
    seeds = [NOMINAL_ARM] + [
        tuple(float(q) for q in rng.uniform(lows, highs)) for _ in range(grid.random_seeds)
    ]
    low, high = robot_model.LIFT_RANGE
    lifts = [round(float(z), 3) for z in np.arange(low, high + 1e-9, grid.lift_step)]
    feasible: list[FeasiblePlacement] = []
    checked = 0
    doors = frozenset(d.name for d in spec.doors)
    for (grill_uv, grill_pose), pitch, yaw in itertools.product(
        grill_poses,
        np.linspace(*grid.pitch_range, grid.pitches),
        np.linspace(*grid.yaw_range, grid.yaws),
    ):
        grasp = side_grasp(can_spec, float(pitch), float(yaw))
        state = State(
            tuple(sorted({**others, "beef_grill": grill_pose}.items())),
            doors,
            RobotConf.make(stand, robot_model.CARRY_LIFT, robot_model.CARRY_ARM),
            grasp,
            0.0,
        )
        for u, v in itertools.product(
            _grid(can_bounds[0], grid.placements), _grid(can_bounds[1], grid.placements)
        ):
            placement = ObjectPose.make(*se2_to_world(frame, u, v), region.top, stand[2])
            sim.set_state(state)
            sim.set_base_only(stand)
            sim.attach(None)
            sim.place_object(can, placement)
            if sim.contacts_of([sim.bodies.objects[can]], robot):
                continue  # PLACE refuses a placement in contact before any motion
            hand = placing_hand(placement, grasp)
            lift = _feasible_lift(domain, state, can, counter, placement, hand, lifts, seeds)
            checked += 1
            if lift is not None:
                feasible.append(
                    FeasiblePlacement(
                        grill_uv, float(pitch), float(yaw), (float(u), float(v)), lift
                    )
                )
                if stop_at_first:
                    return SweepResult(len(grill_poses), checked, tuple(feasible))
    return SweepResult(len(grill_poses), checked, tuple(feasible))


def _feasible_lift(
    domain: Domain,
    state: State,
    can: str,
    counter: str,
    placement: ObjectPose,
    hand: tuple,
    lifts: list[float],
    seeds: list[tuple[float, ...]],
) -> float | None:
    """A lift height from which PLACE's motion puts the can down without a collision."""
    stand = domain.problem.spec.region(counter).base_pose
    for lift, seed in itertools.product(lifts, seeds):
        solution = refine(domain.sim, stand, hand, lift, seed)
        if solution is None:
            continue
        motion = ArmMotion(
            stand,
            solution_conf(solution),
            tuple(reach_waypoints(domain.sim, stand, hand, solution, 0.0, PLACE_CLEARANCE)),
            tuple(leave_waypoints(domain.sim, stand, hand, solution, APPROACH_DISTANCE, 0.0)),
        )
        action = Place(can, "on", counter)
        if domain.samplers._place_motion_free(state, action, placement, motion, Failures()):
            return lift
    return None
