"""PyBullet's own IK (``calculateInverseKinematics``), kept as the reference of the compiled
solver in :mod:`stalm.motion.ik`: ``stalm bench ik`` times both on the same targets and counts
how often each reaches them. No planner calls it.
"""

from __future__ import annotations

import math

import pybullet as p

from stalm.geometry.transforms import Pose3, angle_between_rotations, matrix_from_quat
from stalm.motion.ik import ANGLE_TOLERANCE, POSITION_TOLERANCE, IKSolution
from stalm.world import robot as robot_model
from stalm.world.scene import ARM_JOINTS, GRASP_LINK, Sim

REFINEMENTS = 3
"""IK calls per attempt, each starting where the previous ended (PyBullet's IK is one
damped-least-squares run and often stops short of the target)."""


def pybullet_refine(
    sim: Sim, base: tuple[float, float, float], target: Pose3, lift: float, seed: tuple[float, ...]
) -> IKSolution | None:
    """Up to :data:`REFINEMENTS` IK calls from ``seed``; the solution if FK confirms it."""
    lows = [lo for lo, _ in robot_model.ARM_JOINT_LIMITS]
    highs = [hi for _, hi in robot_model.ARM_JOINT_LIMITS]
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
