"""Speed of IK: the compiled solver beside PyBullet's own, on the same targets.

For each problem, targets are made reachable by construction: a random arm configuration
near the nominal one, at a random lift, at each region's standing pose, put through forward
kinematics; its grasp pose is the target. Each target is then solved from the same seeds
(the nominal arm, then a random configuration) by :func:`stalm.motion.ik.refine` (damped
least squares compiled with numba, what every planner runs) and by
:func:`stalm.motion.ik_reference.pybullet_refine` (PyBullet's ``calculateInverseKinematics``
with joint resets and a forward-kinematics check, what stalm ran before). Wall times of this
process (``time.perf_counter``); both in one run on one machine. ``missed`` counts targets
the reference reached and the compiled solver did not.

Any other arm (``--robot``: a built-in robot or a robot file, :mod:`stalm.world.robot_loader`) is
benchmarked alone,
fixed at the world origin in its own PyBullet client: targets are the tool frames of
configurations drawn uniformly inside its limits, and each is solved from the same seeds
(drawn uniformly too, tried in order until one reaches it) by the compiled
:mod:`stalm.motion.arm_kinematics` (all targets in one batched call) and by PyBullet's
``calculateInverseKinematics`` (:class:`stalm.motion.ik_reference.PyBulletArm`).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from stalm.errors import StalmError
from stalm.geometry.transforms import Pose3, quat_from_matrix
from stalm.motion import ik, panda
from stalm.motion.arm_kinematics import ArmKinematics
from stalm.motion.arm_model import PANDA_NOMINAL_ARM
from stalm.motion.ik_reference import PyBulletArm, pybullet_refine
from stalm.motion.robot_chain import robot_chain
from stalm.world import robot as robot_model
from stalm.world.problem import load_problem
from stalm.world.robot_description import is_builtin_panda
from stalm.world.robot_loader import load_robot
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
        q = np.clip(np.array(PANDA_NOMINAL_ARM) + rng.normal(0.0, 0.5, 7), lows, highs)
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
) -> tuple[float, list[bool]]:
    """Seconds per attempt and whether each target was reached (by the first seed that
    reaches it)."""
    attempts = 0
    reached = []
    start = time.perf_counter()
    for (stand, pose, lift), random_seed in zip(targets, seeds, strict=True):
        hit = False
        for seed in (PANDA_NOMINAL_ARM, random_seed):
            attempts += 1
            if refine(stand, pose, lift, seed) is not None:
                hit = True
                break
        reached.append(hit)
    return (time.perf_counter() - start) / max(attempts, 1), reached


def bench_problem(name: str, count: int = 200, seed: int = 0) -> dict[str, object]:
    """One problem's row: seconds per IK attempt and targets reached, by both solvers."""
    problem = load_problem(name)
    if not is_builtin_panda(problem.robot):
        raise StalmError(
            f"{problem.name} names the robot {problem.robot.name!r}: a problem's IK is "
            f"benchmarked for the Panda only; use --robot {problem.robot.name} (the arm alone)"
        )
    rng = np.random.default_rng(seed)
    with Sim(problem.spec) as sim:
        targets = reachable_targets(sim, count, rng)
        lows = [lo for lo, _ in robot_model.ARM_JOINT_LIMITS]
        highs = [hi for _, hi in robot_model.ARM_JOINT_LIMITS]
        seeds = [tuple(float(v) for v in rng.uniform(lows, highs)) for _ in targets]
        ik.refine(sim, *targets[0][:2], targets[0][2], PANDA_NOMINAL_ARM)  # compiled code loaded
        compiled_s, compiled_reached = _solve_all(
            lambda stand, pose, lift, start: ik.refine(sim, stand, pose, lift, start),
            targets,
            seeds,
        )
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
        "reached": sum(compiled_reached),
        "reference_reached": sum(reference_reached),
        "missed": _missed(compiled_reached, reference_reached),
    }


def _missed(reached: list[bool], reference_reached: list[bool]) -> int:
    """Targets the reference reached and the compiled solver did not."""
    return sum(ref and not new for new, ref in zip(reached, reference_reached, strict=True))


def bench_arm(robot: str, count: int = 200, seed: int = 0, attempts: int = 20) -> dict[str, object]:
    """One arm's row (see the module): seconds per target and targets reached by both
    solvers, each trying the same ``attempts`` seeds per target in order."""
    loaded = load_robot(robot)
    chain = robot_chain(loaded)
    kinematics = ArmKinematics(chain)
    rng = np.random.default_rng(seed)
    reference = PyBulletArm(chain)
    try:
        base = reference.base
        targets = kinematics.frames_batch(base, kinematics.random_configurations(rng, count))[:, -1]
        seeds = kinematics.random_configurations(rng, count * attempts).reshape(
            count, attempts, chain.dof
        )
        tolerances = (ik.POSITION_TOLERANCE, ik.ANGLE_TOLERANCE)
        kinematics.solve_batch(base, targets[:1], seeds[:1], *tolerances)  # compiled code loaded
        start = time.perf_counter()
        result = kinematics.solve_batch(base, targets, seeds, *tolerances)
        compiled_s = (time.perf_counter() - start) / count
        start = time.perf_counter()
        reference_reached = [
            any(reference.refine(target, start_q) is not None for start_q in target_seeds)
            for target, target_seeds in zip(targets, seeds, strict=True)
        ]
        reference_s = (time.perf_counter() - start) / count
    finally:
        reference.close()
    return {
        "robot": loaded.name,
        "joints": chain.dof,
        "targets": count,
        "seeds": attempts,
        "solve_s": compiled_s,
        "reference_solve_s": reference_s,
        "reached": int(result.solved.sum()),
        "reference_reached": sum(reference_reached),
        "missed": _missed([bool(v) for v in result.solved], reference_reached),
        "mean_attempts": float(result.attempts.mean()),
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
