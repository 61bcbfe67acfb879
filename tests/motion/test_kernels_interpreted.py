"""The compiled kernels against their own Python source, run by the interpreter.

numba compiles the forward kinematics, IK and candidate tests of :mod:`stalm.motion.panda`,
:mod:`stalm.motion.collision_primitives` and :mod:`stalm.motion.collision_kernels`; compiled
code is not traced by coverage and a compiler could change what it computes. Here every
compiled function of those modules is swapped for the Python function it was compiled from
(``Dispatcher.py_func``), so the same source runs in the interpreter, and the answers must be
the compiled ones: the same candidate bodies at every step, the same IK solutions within
1e-9 (compiled code may fuse multiply-adds the interpreter rounds twice).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

import numpy as np
from numba.core.dispatcher import Dispatcher

from stalm.motion import colliders, collision_kernels, collision_primitives, ik, panda
from stalm.motion.arm_model import PANDA_NOMINAL_ARM
from stalm.motion.arm_motion import interpolate_waypoints
from stalm.motion.colliders import BatchCollider
from stalm.motion.grasps import (
    PITCH_RANGE,
    YAW_RANGE,
    gripper_target,
    nearest_grasp_point,
    sample_grasp_angles,
)
from stalm.motion.manipulation import Manipulator
from stalm.world import robot as robot_model
from stalm.world.problem import Problem
from stalm.world.scene import Sim
from stalm.world.state import Grasp

COMPILED_MODULES = (panda, collision_primitives, collision_kernels, colliders)


@contextmanager
def interpreted(modules: tuple[ModuleType, ...] = COMPILED_MODULES) -> Iterator[int]:
    """Within the block, each module's compiled functions are their Python source; yields
    how many were swapped."""
    swapped = [
        (module, name, value)
        for module in modules
        for name, value in list(vars(module).items())
        if isinstance(value, Dispatcher)
    ]
    for module, name, value in swapped:
        setattr(module, name, value.py_func)
    try:
        yield len(swapped)
    finally:
        for module, name, value in swapped:
            setattr(module, name, value)


def _pick_motions(problem: Problem, sim: Sim, count: int) -> list[tuple[tuple, list]]:
    """Arm configurations (interpolated) of ``count`` pick motions of each of the problem's
    objects, from its region's standing pose, drawn from a seeded generator."""
    rng = np.random.default_rng(3)
    hands = Manipulator(sim, "pybullet")
    motions = []
    for obj in problem.spec.objects:
        stand = problem.spec.region(obj.on).base_pose
        point = nearest_grasp_point(obj, problem.initial_state.pose(obj.name), stand)
        for _ in range(count):
            pitch, yaw = sample_grasp_angles(rng, PITCH_RANGE, YAW_RANGE)
            target = gripper_target(point, stand[2], pitch, yaw)
            for arm in hands.picks(stand, target, rng, 4):
                motions.append((stand, interpolate_waypoints((*arm.into, *arm.out))))
                break
    return motions


def test_the_candidate_test_and_fk_agree_with_their_source(problems: dict[str, Problem]) -> None:
    with Sim(problems["P2"].spec) as sim:
        motions = _pick_motions(problems["P2"], sim, 2)
        assert len(motions) >= 4
        collider = BatchCollider(sim)
        ignore = {sim.bodies.base}
        compiled = [
            collider._candidates(np.tile(stand, (len(confs), 1)), np.asarray(confs), ignore, False)
            for stand, confs in motions
        ]
        with interpreted() as count:
            assert count >= 15  # every compiled function of the four modules
            again = [
                collider._candidates(
                    np.tile(stand, (len(confs), 1)), np.asarray(confs), ignore, False
                )
                for stand, confs in motions
            ]
    flagged = 0
    for (flags, reach), (flags_again, reach_again) in zip(compiled, again, strict=True):
        assert np.array_equal(flags, flags_again)
        assert np.allclose(reach, reach_again, atol=1e-9)
        flagged += int(flags.sum())
    assert flagged > 0  # the motions come near something: the sphere tests really ran


def test_routes_and_held_objects_agree_with_their_source(problems: dict[str, Problem]) -> None:
    """The box tests: the base's column along a route, a can and the grill in the hand."""
    problem = problems["P5"]
    with Sim(problem.spec) as sim:
        collider = BatchCollider(sim)
        region = problem.spec.regions[0]
        route = np.linspace(problem.spec.robot.base, region.base_pose, 60)
        arm = np.tile((1.0, *PANDA_NOMINAL_ARM), (len(route), 1))
        cases: list[tuple[np.ndarray, np.ndarray, bool]] = []
        motions = _pick_motions(problem, sim, 1)
        for obj in ("coke", "beef_grill"):
            stand, confs = motions[0]
            cases.append((np.tile(stand, (len(confs), 1)), np.asarray(confs), False))
            cases.append((route, arm, True))
            sim.attach(Grasp.make(obj, (0.0, 0.0, 0.04), (0.0, 0.0, 0.0, 1.0)))
            held = [collider._candidates(a, b, {sim.bodies.base}, c) for a, b, c in cases[-2:]]
            with interpreted():
                again = [collider._candidates(a, b, {sim.bodies.base}, c) for a, b, c in cases[-2:]]
            sim.attach(None)
            for (flags, _), (flags_again, _) in zip(held, again, strict=True):
                assert np.array_equal(flags, flags_again), obj
            assert any(flags.any() for flags, _ in held), obj


def test_ik_agrees_with_its_source(problems: dict[str, Problem]) -> None:
    rng = np.random.default_rng(4)
    stand = (0.0, 0.0, 0.0)
    targets = []
    for _ in range(6):
        lift = float(rng.uniform(0.8, 1.0))
        q = np.array(PANDA_NOMINAL_ARM) + rng.normal(0.0, 0.3, 7)
        frame = panda.link_frames(panda.base_frame(robot_model.arm_mount(stand, lift)), q)
        targets.append((lift, frame[panda.GRASP]))

    def solve_all() -> list[tuple[tuple[float, ...], float, float]]:
        return [
            panda.solve_pose(
                panda.base_frame(robot_model.arm_mount(stand, lift)), target, PANDA_NOMINAL_ARM
            )
            for lift, target in targets
        ]

    compiled = solve_all()
    with interpreted():
        again = solve_all()
    for (q, position, angle), (q_again, position_again, angle_again) in zip(
        compiled, again, strict=True
    ):
        assert np.allclose(q, q_again, atol=1e-9)
        assert abs(position - position_again) < 1e-9 and abs(angle - angle_again) < 1e-9
    assert sum(position < ik.POSITION_TOLERANCE for _, position, _ in compiled) >= 4


def test_the_prunings_find_what_every_sphere_against_every_primitive_finds(
    problems: dict[str, Problem],
) -> None:
    """The candidate test skips links, parts and primitives by bounding spheres and boxes;
    without any of that (every sphere of the model against every box and cylinder of P3's
    crowded scene, in numpy) the same bodies are candidates at every configuration of its
    pick motions, and of the same motions with the joints shaken (so that the arm strikes
    shelves and neighbours), and some are; a body a sphere grazes (within 1e-9 m² of touching,
    which rounding on another CPU may decide either way) may be either."""
    graze = 1e-9  # m²
    rng = np.random.default_rng(5)
    with Sim(problems["P3"].spec) as sim:
        motions = _pick_motions(problems["P3"], sim, 1)
        for stand, confs in list(motions):
            shaken = np.asarray(confs, dtype=float)
            shaken[:, 1:] += rng.normal(0.0, 0.6, shaken[:, 1:].shape)
            motions.append((stand, [tuple(conf) for conf in shaken]))
        collider = BatchCollider(sim)
        scene = collider._scene
        boxes, cylinders = scene.world(())
        spheres = scene.spheres
        marked = 0
        for stand, confs in motions:
            array = np.asarray(confs, dtype=float).reshape(-1, 8)
            stands = np.tile(np.asarray(stand, dtype=float), (len(array), 1))
            flags, _ = collider._candidates(stands, array, (), False)
            for step, conf in enumerate(array):
                frames = panda.link_frames(
                    panda.base_frame(robot_model.arm_mount(stand, conf[0])), conf[1:]
                )
                link = frames[spheres.link]
                centres = np.einsum("nij,nj->ni", link[:, :3, :3], spheres.centre)
                centres += link[:, :3, 3]
                # (squared distance - squared radius) of every sphere's nearest approach to
                # each body; within graze of 0 another CPU's rounding may decide either way
                gap = np.full(flags.shape[1], np.inf)
                for box in boxes:
                    rotation = box[6:15].reshape(3, 3)
                    local = (centres - box[:3]) @ rotation
                    excess = np.maximum(np.abs(local) - box[3:6], 0.0)
                    margin = (excess**2).sum(axis=1) - spheres.radius**2
                    if box[15] >= 0:
                        gap[int(box[15])] = min(gap[int(box[15])], margin.min())
                for x, y, bottom, top, radius, column in cylinders:
                    radial = np.maximum(np.hypot(centres[:, 0] - x, centres[:, 1] - y) - radius, 0)
                    axial = np.maximum(np.maximum(bottom - centres[:, 2], centres[:, 2] - top), 0)
                    margin = radial**2 + axial**2 - spheres.radius**2
                    if column >= 0:
                        gap[int(column)] = min(gap[int(column)], margin.min())
                surely, maybe = gap < -graze, gap < graze
                found = flags[step]
                assert not np.any(surely & ~found), f"missed at step {step} at {stand}"
                assert not np.any(found & ~maybe), f"extra at step {step} at {stand}"
                marked += int(surely.sum())
    assert marked > 0
