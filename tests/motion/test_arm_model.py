"""The arm model: the Panda's compiled code against the Panda read from its URDF, and another
arm (the xArm 6 of its robot file) against PyBullet, in frames, spheres and predicates."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pybullet as p
import pytest

from stalm.domain.mdp import Domain
from stalm.errors import StalmError
from stalm.motion.arm_model import PandaArm, UrdfArm, arm_of, urdf_arm
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.samples import PredicateSettings
from stalm.world.problem import Problem, load_problem
from stalm.world.robot import ArmMount
from stalm.world.robot_loader import robot_named
from stalm.world.scene import Sim

FRAME_TOLERANCE_M = 1e-9
"""The Panda's compiled frames and the generic chain's: the same transforms, multiplied in
another order."""
PYBULLET_TOLERANCE = 1e-6
"""Frames against PyBullet's ``getLinkState`` (single-precision quaternions inside)."""


@pytest.fixture(scope="module")
def xarm_p2() -> Problem:
    return load_problem("P2").with_robot("xarm6")


def _random_stand(rng: np.random.Generator) -> tuple[float, float, float]:
    return tuple(float(v) for v in rng.uniform(-3, 3, 3))  # type: ignore[return-value]


def _random_arm(rng: np.random.Generator, robot_name: str) -> np.ndarray:
    limits = np.array(robot_named(robot_name).joint_limits)
    return rng.uniform(np.maximum(limits[:, 0], -3.1), np.minimum(limits[:, 1], 3.1))


def test_the_panda_on_its_compiled_code_is_the_panda_read_from_its_urdf() -> None:
    compiled = arm_of_problem(load_problem("P2"))
    assert isinstance(compiled, PandaArm)
    reference = urdf_arm(robot_named("panda"))
    rng = np.random.default_rng(0)
    for _ in range(100):
        mount = ArmMount(*rng.uniform(-3, 3, 2), float(rng.uniform(0.55, 1.45)), rng.uniform(-3, 3))
        assert np.allclose(
            compiled.base_frame(mount), reference.base_frame(mount), atol=FRAME_TOLERANCE_M
        )
        q = _random_arm(rng, "panda")
        fast = compiled.frames(compiled.base_frame(mount), q)
        slow = reference.frames(reference.base_frame(mount), q)
        assert np.allclose(fast[:8], slow[:8], atol=FRAME_TOLERANCE_M)  # base and links 1-7
        assert np.allclose(
            fast[compiled.grasp_frame], slow[reference.grasp_frame], atol=FRAME_TOLERANCE_M
        )
    assert compiled.lows.tolist() == reference.lows.tolist()


@pytest.mark.parametrize("robot", ["panda", "xarm6", "iiwa_gripper"])
def test_step_frames_are_the_frames_of_each_step(robot: str) -> None:
    problem = load_problem("P2") if robot == "panda" else load_problem("P2").with_robot(robot)
    arm = arm_of_problem(problem)
    rng = np.random.default_rng(1)
    stands = rng.uniform(-3, 3, (20, 3))
    confs = np.column_stack([rng.uniform(0.6, 1.4, 20), [_random_arm(rng, robot) for _ in stands]])
    frames, reach = arm.step_frames(stands, confs)
    for k, (stand, conf) in enumerate(zip(stands, confs, strict=True)):
        with Sim(problem.spec) as sim:
            mount = sim.arm_mount(tuple(stand), conf[0])
        one = arm.frames(arm.base_frame(mount), conf[1:])
        assert np.allclose(frames[k], one, atol=FRAME_TOLERANCE_M)
        grasp = one[arm.grasp_frame]
        assert np.allclose(reach[k], [mount.x, mount.y, grasp[0, 3], grasp[1, 3]], atol=1e-9)


def arm_of_problem(problem: Problem) -> PandaArm | UrdfArm:
    with Sim(problem.spec) as sim:
        arm = arm_of(sim)
    assert isinstance(arm, PandaArm | UrdfArm)
    return arm


def test_the_xarms_frames_are_pybullets(xarm_p2: Problem) -> None:
    rng = np.random.default_rng(2)
    with Sim(xarm_p2.spec) as sim:
        arm = arm_of(sim)
        assert isinstance(arm, UrdfArm) and arm.dof == 6
        joints = sim.bodies.joints.arm
        for _ in range(40):
            stand, lift, q = (
                _random_stand(rng),
                float(rng.uniform(0.6, 1.4)),
                _random_arm(rng, "xarm6"),
            )
            sim.set_arm(stand, lift, tuple(q))
            frames = arm.frames(arm.base_frame(sim.arm_mount(stand, lift)), q)
            for index, joint in enumerate(joints, start=1):
                state = p.getLinkState(
                    sim.bodies.arm, joint, computeForwardKinematics=True, physicsClientId=sim.client
                )
                rotation = np.array(p.getMatrixFromQuaternion(state[5])).reshape(3, 3)
                assert np.allclose(frames[index][:3, 3], state[4], atol=PYBULLET_TOLERANCE)
                assert np.allclose(frames[index][:3, :3], rotation, atol=PYBULLET_TOLERANCE)
            grasp = frames[arm.grasp_frame]
            position, orientation = sim.gripper_pose()
            assert np.allclose(grasp[:3, 3], position, atol=PYBULLET_TOLERANCE)
            rotation = np.array(p.getMatrixFromQuaternion(orientation)).reshape(3, 3)
            assert np.allclose(grasp[:3, :3], rotation, atol=PYBULLET_TOLERANCE)


def test_the_xarms_spheres_flag_every_pybullet_contact(xarm_p2: Problem) -> None:
    """A probe PyBullet finds in contact with the arm (gripper included) meets a sphere."""
    rng = np.random.default_rng(3)
    contacts = 0
    with Sim(xarm_p2.spec) as sim:
        arm = arm_of(sim)
        model = arm.spheres
        c = sim.client
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05, 0.2, 0.02], physicsClientId=c)
        probe = p.createMultiBody(1.0, shape, -1, [0, 0, -5], physicsClientId=c)
        for trial in range(800):
            lift, q = float(rng.uniform(0.6, 1.3)), _random_arm(rng, "xarm6")
            sim.set_arm((0.0, 0.0, 0.0), lift, tuple(q))
            frames = arm.frames(arm.base_frame(sim.arm_mount((0.0, 0.0, 0.0), lift)), q)
            centres = np.einsum("nij,nj->ni", frames[model.link][:, :3, :3], model.centre)
            centres += frames[model.link][:, :3, 3]
            anchor = centres[rng.integers(len(centres))] + rng.normal(0, 0.06, 3)
            tilt = p.getQuaternionFromEuler([*rng.uniform(-0.3, 0.3, 2), rng.uniform(-3, 3)])
            p.resetBasePositionAndOrientation(probe, anchor.tolist(), tilt, physicsClientId=c)
            touched = [
                point
                for point in p.getClosestPoints(sim.bodies.arm, probe, 0.0, physicsClientId=c)
                if point[8] < -1e-3
            ]
            if not touched:
                continue
            contacts += 1
            rotation = np.array(p.getMatrixFromQuaternion(tilt)).reshape(3, 3)
            local = (centres - anchor) @ rotation
            outside = np.maximum(np.abs(local) - [0.05, 0.2, 0.02], 0.0)
            assert (np.linalg.norm(outside, axis=1) < model.radius).any(), f"trial {trial}"
    assert contacts > 300


def test_both_engines_give_the_xarm_the_same_predicates(xarm_p2: Problem) -> None:
    domain = Domain.create(xarm_p2)
    try:
        caches = [
            PredicateEngine(
                xarm_p2, domain.sim, domain.base_planner, PredicateSettings(engine=engine)
            ).compute(xarm_p2.initial_state)
            for engine in ("pybullet", "batched")
        ]
    finally:
        domain.close()
    reference, batched = caches
    assert batched.literals == reference.literals and batched.unreachable == reference.unreachable
    for key, record in reference.picks.items():
        assert [m.hits for m in batched.picks[key].motions] == [m.hits for m in record.motions]


def test_a_problem_for_another_robot_names_it_and_hashes_apart(xarm_p2: Problem) -> None:
    panda = load_problem("P2")
    assert xarm_p2.spec.robot.file == "xarm6" and xarm_p2.robot.name == "xarm6"
    assert xarm_p2.content_hash != panda.content_hash
    assert "file" not in panda.spec.model_dump(mode="json")["robot"]
    assert len(xarm_p2.initial_state.robot.arm) == 6
    assert xarm_p2.initial_state.robot.arm == xarm_p2.robot.spec.carry


def test_a_robot_that_cannot_plan_is_named(tmp_path: Path) -> None:
    with pytest.raises(
        StalmError,
        match=r"no robot 'nope'.*iiwa, iiwa_gripper, iiwa_gripper_table, panda, panda_table",
    ):
        load_problem("P2").with_robot("nope")
    with pytest.raises(StalmError, match="'iiwa' has no gripper"):
        load_problem("P2").with_robot("iiwa")
    fixed = tmp_path / "tabletop.yaml"
    text = (Path(robot_named("xarm6").source)).read_text()
    start = text.index("mount:")
    end = text.index("\ncarry:")
    urdf = robot_named("xarm6").urdf_path
    fixed.write_text(
        text[:start].replace("pybullet_data:xarm/xarm6_with_gripper.urdf", str(urdf))
        + "mount: {kind: fixed, xyz: [0.0, 0.0, 0.75]}"
        + text[end:]
    )
    with pytest.raises(StalmError, match="a fixed arm works from one pose"):
        load_problem("P2").with_robot(str(fixed))


def test_the_roadmap_plans_for_a_wider_base_as_it_is(tmp_path: Path) -> None:
    from stalm.motion.roadmap import RoadmapSettings, fitted_to

    settings = RoadmapSettings()
    with Sim(load_problem("P2").spec) as sim:
        assert fitted_to(settings, sim) is settings  # the Panda's: its cache keys unchanged
    xarm = Path(robot_named("xarm6").source)
    wide = tmp_path / "wide.yaml"
    wide.write_text(
        xarm.read_text()
        .replace("base_radius: 0.3", "base_radius: 0.45")
        .replace("pybullet_data:xarm/xarm6_with_gripper.urdf", str(robot_named("xarm6").urdf_path))
    )
    with Sim(load_problem("P2").with_robot(str(wide)).spec) as sim:
        assert fitted_to(settings, sim).proxy_radius == pytest.approx(0.47, abs=1e-12)
