"""Inverse kinematics for the gripper with random restarts, and the lift height it needs.

Damped least squares is local, so each attempt starts from an arm configuration (the nominal
one, or a random one drawn from the passed generator) and is accepted only if forward
kinematics puts the grasp point within :data:`POSITION_TOLERANCE` and the orientation within
:data:`ANGLE_TOLERANCE` of the target; the joints stay inside their limits. The solver is
:mod:`stalm.motion.arm_model`'s (the URDF's chain, compiled): IK moves no PyBullet body,
so the simulator is left as it was. PyBullet's own ``calculateInverseKinematics`` did the same
steps at about a millisecond per attempt (calls, joint resets and a forward-kinematics check);
it is kept as the reference of ``stalm bench ik`` (:mod:`stalm.motion.ik_reference`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from stalm.geometry.transforms import Pose3, matrix_from_quat
from stalm.motion.arm_model import ArmModel, arm_of
from stalm.world.scene import Sim

POSITION_TOLERANCE = 0.005
ANGLE_TOLERANCE = 0.03
ITERATIONS = 150
"""Damped-least-squares steps per attempt (most converge in under 30)."""


@dataclass(frozen=True)
class IKSolution:
    lift: float
    arm: tuple[float, ...]


def lift_candidates(sim: Sim, target_z: float) -> tuple[float, ...]:
    """Lift heights to try for a target height: shoulder near the target first."""
    low, high = sim.robot.platform.lift_range
    if low == high:
        return (low,)  # a fixed arm: its mount's height
    preferred = target_z - arm_of(sim).shoulder_above_mount + 0.05
    values = []
    for offset in (0.0, 0.15, -0.15, 0.3):
        value = round(min(high, max(low, preferred + offset)), 3)
        if value not in values:
            values.append(value)
    return tuple(values)


def target_matrix(target: Pose3) -> np.ndarray:
    """A gripper pose (position, quaternion) as a 4x4 transform."""
    matrix = np.eye(4)
    matrix[:3, :3] = matrix_from_quat(target[1])
    matrix[:3, 3] = target[0]
    return matrix


def refine(
    sim: Sim,
    base: tuple[float, float, float],
    target: Pose3,
    lift: float,
    seed: tuple[float, ...],
    arm: ArmModel | None = None,
) -> IKSolution | None:
    """Damped least squares from ``seed`` at ``lift``; the solution if it reaches ``target``
    within the tolerances."""
    arm = arm_of(sim) if arm is None else arm
    frame = arm.base_frame(sim.arm_mount(base, lift))
    q, position, angle = arm.solve_pose(frame, target_matrix(target), seed, ITERATIONS)
    if position <= POSITION_TOLERANCE and angle <= ANGLE_TOLERANCE:
        return IKSolution(lift, q)
    return None


def solve_ik_from(
    sim: Sim, base: tuple[float, float, float], target: Pose3, start: IKSolution
) -> IKSolution | None:
    """IK seeded at a known nearby solution and its lift (for approach and lift-off poses)."""
    return refine(sim, base, target, start.lift, start.arm)


def solve_ik(
    sim: Sim,
    base: tuple[float, float, float],
    target: Pose3,
    rng: np.random.Generator,
    attempts: int = 6,
) -> IKSolution | None:
    """An arm configuration putting the grasp point at ``target`` from ``base``, or None:
    the first of :func:`solutions_by_lift`."""
    return next(solutions_by_lift(sim, base, target, rng, attempts), None)


def solutions_by_lift(
    sim: Sim,
    base: tuple[float, float, float],
    target: Pose3,
    rng: np.random.Generator,
    attempts: int = 6,
) -> Iterator[IKSolution]:
    """Arm configurations putting the grasp point at ``target`` from ``base``, at most one per
    lift height, in the order tried: lift heights cycle through :func:`lift_candidates`, two
    attempts each, the first from :data:`NOMINAL_ARM` and the second from a random
    configuration drawn from ``rng``. A caller whose motion at one lift collides asks for the
    next (an object carried low can be dragged through its table as the arm folds)."""
    arm = arm_of(sim)
    lows = [lo for lo, _ in sim.robot.joint_limits]
    highs = [hi for _, hi in sim.robot.joint_limits]
    candidates = lift_candidates(sim, target[0][2])
    attempt = 0
    while attempt < attempts:
        lift = candidates[(attempt // 2) % len(candidates)]
        seed: tuple[float, ...]
        if attempt % 2 == 0:
            seed = arm.nominal_arm
        else:
            seed = tuple(float(v) for v in rng.uniform(lows, highs))
        solution = refine(sim, base, target, lift, seed, arm)
        attempt += 1
        if solution is not None:
            yield solution
            attempt += attempt % 2  # the next lift's first attempt
