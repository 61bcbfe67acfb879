"""Inverse kinematics for the gripper with random restarts, and the lift height it needs.

PyBullet's damped-least-squares IK is local, so each attempt starts from a random arm
configuration (drawn from the passed generator) and is accepted only if forward kinematics
puts the grasp point within :data:`POSITION_TOLERANCE` and the orientation within
:data:`ANGLE_TOLERANCE` of the target and every joint is inside its limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p

from stalm.geometry.transforms import Pose3, angle_between_rotations, matrix_from_quat
from stalm.world import robot as robot_model
from stalm.world.scene import ARM_JOINTS, GRASP_LINK, Sim

POSITION_TOLERANCE = 0.005
ANGLE_TOLERANCE = 0.03
SHOULDER_ABOVE_MOUNT = 0.333
REFINEMENTS = 3
"""IK calls per restart, each starting where the previous ended (PyBullet's IK is one
damped-least-squares run and often stops short of the target)."""
NOMINAL_ARM = (0.0, 0.3, 0.0, -1.8, 0.0, 2.1, 0.785)
"""First seed: the arm reaching forward at mid height, where most grasps lie."""


@dataclass(frozen=True)
class IKSolution:
    lift: float
    arm: tuple[float, ...]


def lift_candidates(target_z: float) -> tuple[float, ...]:
    """Lift heights to try for a target height: shoulder near the target first."""
    low, high = robot_model.LIFT_RANGE
    preferred = target_z - SHOULDER_ABOVE_MOUNT + 0.05
    values = []
    for offset in (0.0, 0.15, -0.15, 0.3):
        value = round(min(high, max(low, preferred + offset)), 3)
        if value not in values:
            values.append(value)
    return tuple(values)


def solve_ik_from(
    sim: Sim, base: tuple[float, float, float], target: Pose3, start: IKSolution
) -> IKSolution | None:
    """IK seeded at a known nearby solution and its lift (for approach and lift-off poses)."""
    return _refine(sim, base, target, start.lift, start.arm)


def _limits() -> tuple[list[float], list[float], list[float]]:
    lows = [lo for lo, _ in robot_model.ARM_JOINT_LIMITS]
    highs = [hi for _, hi in robot_model.ARM_JOINT_LIMITS]
    return lows, highs, [hi - lo for lo, hi in robot_model.ARM_JOINT_LIMITS]


def _refine(
    sim: Sim, base: tuple[float, float, float], target: Pose3, lift: float, seed: tuple[float, ...]
) -> IKSolution | None:
    """Up to :data:`REFINEMENTS` IK calls from ``seed``; the solution if FK confirms it."""
    lows, highs, _ = _limits()
    target_rot = matrix_from_quat(target[1])
    held, held_offset = sim.held, sim.held_yaw_offset
    sim.attach(None)
    try:
        q = seed
        for _ in range(REFINEMENTS):
            sim.set_arm(base, lift, q)
            # plain damped least squares: without null-space terms it converges as often here
            # and twice as fast; joint limits are enforced by the check below
            solution = p.calculateInverseKinematics(
                sim.bodies.arm,
                GRASP_LINK,
                list(target[0]),
                list(target[1]),
                maxNumIterations=60,
                residualThreshold=1e-5,
                physicsClientId=sim.client,
            )
            q = tuple(
                min(hi, max(lo, float(v)))
                for v, lo, hi in zip(solution[: len(ARM_JOINTS)], lows, highs, strict=True)
            )
            sim.set_arm(base, lift, q)
            pos, orn = sim.gripper_pose()
            if (
                math.dist(pos, target[0]) <= POSITION_TOLERANCE
                and angle_between_rotations(matrix_from_quat(orn), target_rot) <= ANGLE_TOLERANCE
            ):
                return IKSolution(lift, q)
        return None
    finally:
        sim.attach(held, held_offset)


def solve_ik(
    sim: Sim,
    base: tuple[float, float, float],
    target: Pose3,
    rng: np.random.Generator,
    attempts: int = 6,
) -> IKSolution | None:
    """An arm configuration putting the grasp point at ``target`` from ``base``, or None.

    The first restart starts from :data:`NOMINAL_ARM`, later ones from random configurations;
    lift heights cycle through :func:`lift_candidates`.
    """
    lows, highs, _ = _limits()
    candidates = lift_candidates(target[0][2])
    for attempt in range(attempts):
        lift = candidates[(attempt // 2) % len(candidates)]
        seed: tuple[float, ...]
        if attempt % 2 == 0:
            seed = NOMINAL_ARM
        else:
            seed = tuple(float(v) for v in rng.uniform(lows, highs))
        solution = _refine(sim, base, target, lift, seed)
        if solution is not None:
            return solution
    return None
