"""Speed of IK: the compiled solver beside PyBullet's own, on the same targets.

For each problem, targets are made reachable by construction: a random arm configuration
near the nominal one, at a random lift, at each region's standing pose, put through forward
kinematics; its grasp pose is the target. Each target is then solved from the same seeds
(the nominal arm, then a random configuration) by :func:`stalm.motion.ik.refine` (damped
least squares compiled with numba, what every planner runs) and by
:func:`stalm.motion.ik_reference.pybullet_refine` (PyBullet's ``calculateInverseKinematics``
with joint resets and a forward-kinematics check, what stalm ran before). Wall times of this
process (``time.perf_counter``); both in one run on one machine.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from stalm.geometry.transforms import Pose3, quat_from_matrix
from stalm.motion import ik, panda
from stalm.motion.ik_reference import pybullet_refine
from stalm.world import robot as robot_model
from stalm.world.problem import load_problem
from stalm.world.scene import Sim

Target = tuple[tuple[float, float, float], Pose3, float]
"""A standing pose, a gripper pose reachable from it, and the lift it was made at."""


def reachable_targets(sim: Sim, count: int, rng: np.random.Generator) -> list[Target]:
    """``count`` targets reachable from the problem's standing poses (see the module)."""
    stands = [region.base_pose for region in sim.problem.regions]
    lows = np.array([lo for lo, _ in robot_model.ARM_JOINT_LIMITS])
    highs = np.array([hi for _, hi in robot_model.ARM_JOINT_LIMITS])
    targets = []
    for index in range(count):
        stand = stands[index % len(stands)]
        lift = float(rng.uniform(*robot_model.LIFT_RANGE))
        q = np.clip(np.array(ik.NOMINAL_ARM) + rng.normal(0.0, 0.5, 7), lows, highs)
        frame = panda.link_frames(panda.base_frame(robot_model.arm_mount(stand, lift)), q)
        grasp = frame[panda.GRASP]
        x, y, z = (float(v) for v in grasp[:3, 3])
        pose: Pose3 = ((x, y, z), quat_from_matrix(grasp[:3, :3]))
        targets.append((stand, pose, lift))
    return targets


def _solve_all(
    refine: Callable[[tuple[float, float, float], Pose3, float, tuple[float, ...]], object],
    targets: list[Target],
    seeds: list[tuple[float, ...]],
) -> tuple[float, int]:
    """Seconds per attempt and targets reached (the first seed that reaches one counts)."""
    attempts = reached = 0
    start = time.perf_counter()
    for (stand, pose, lift), random_seed in zip(targets, seeds, strict=True):
        for seed in (ik.NOMINAL_ARM, random_seed):
            attempts += 1
            if refine(stand, pose, lift, seed) is not None:
                reached += 1
                break
    return (time.perf_counter() - start) / max(attempts, 1), reached


def bench_problem(name: str, count: int = 200, seed: int = 0) -> dict[str, object]:
    """One problem's row: seconds per IK attempt and targets reached, by both solvers."""
    problem = load_problem(name)
    rng = np.random.default_rng(seed)
    with Sim(problem.spec) as sim:
        targets = reachable_targets(sim, count, rng)
        lows = [lo for lo, _ in robot_model.ARM_JOINT_LIMITS]
        highs = [hi for _, hi in robot_model.ARM_JOINT_LIMITS]
        seeds = [tuple(float(v) for v in rng.uniform(lows, highs)) for _ in targets]
        ik.refine(*targets[0][:2], targets[0][2], ik.NOMINAL_ARM)  # compiled code loaded
        compiled_s, compiled_reached = _solve_all(ik.refine, targets, seeds)
        reference_s, reference_reached = _solve_all(
            lambda stand, pose, lift, start: pybullet_refine(sim, stand, pose, lift, start),
            targets,
            seeds,
        )
    return {
        "problem": problem.name,
        "targets": len(targets),
        "attempt_s": compiled_s,
        "reference_attempt_s": reference_s,
        "reached": compiled_reached,
        "reference_reached": reference_reached,
    }


def run(
    names: list[str], count: int, seed: int, report: Callable[[dict[str, object]], None]
) -> list[dict[str, object]]:
    rows = []
    for name in names:
        row = bench_problem(name, count, seed)
        report(row)
        rows.append(row)
    return rows
