"""Kinematics of any serial arm read from a URDF, against the Panda's hard-wired code and
against PyBullet; the chain reader's refusals."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pybullet as p
import pytest

from stalm.errors import StalmError
from stalm.motion import arm_kinematics, dls_kernels, ik, panda
from stalm.motion.arm_kinematics import ArmKinematics
from stalm.motion.ik_reference import PyBulletArm
from stalm.motion.robot_chain import robot_chain
from stalm.motion.urdf_chain import UrdfChain, read_chain
from stalm.world import robot as robot_model
from stalm.world.robot_loader import builtin_robots, load_robot
from tests.motion.test_kernels_interpreted import interpreted

STATE_TOLERANCE = 2e-6
"""PyBullet's link states are single precision: about 1e-7 relative, measured 7.5e-7 m."""


# A 6-joint arm of boxes and cylinders: axes along x, y, z and a slanted one, a rotated and
# offset inertial frame at the root (PyBullet places that), a fixed joint inside the chain and
# one after it, a continuous joint, and a prismatic finger beyond the tool link.
TEST_ARM = """<?xml version="1.0"?>
<robot name="test_arm">
  <link name="world"><inertial><origin xyz="0.03 -0.02 0.05" rpy="0.1 0.2 0.3"/>
    <mass value="2"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/>
  </inertial></link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base"/>
    <origin xyz="0.1 0 0.02" rpy="0 0 0.5"/></joint>
  {links}
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="2.5" effort="10"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.15" rpy="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" velocity="2" effort="10"/></joint>
  <joint name="elbow_spacer" type="fixed"><parent link="l2"/><child link="spacer"/>
    <origin xyz="0 0 0.25" rpy="0 0.2 0"/></joint>
  <joint name="j3" type="revolute"><parent link="spacer"/><child link="l3"/>
    <origin xyz="0 0 0.05"/><axis xyz="1 0 0"/>
    <limit lower="-2.5" upper="2.5" velocity="2" effort="10"/></joint>
  <joint name="j4" type="continuous"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.02 0 0.2"/><axis xyz="0 0 1"/><limit velocity="3" effort="5"/></joint>
  <joint name="j5" type="revolute"><parent link="l4"/><child link="l5"/>
    <origin xyz="0 0 0.1" rpy="0 0 0.4"/><axis xyz="0.6 0.8 0"/>
    <limit lower="-2" upper="2" velocity="3" effort="5"/></joint>
  <joint name="j6" type="revolute"><parent link="l5"/><child link="l6"/>
    <origin xyz="0 0.01 0.08"/><axis xyz="0 0 -1"/>
    <limit lower="-3" upper="3" velocity="3" effort="5"/></joint>
  <joint name="flange" type="fixed"><parent link="l6"/><child link="hand"/>
    <origin xyz="0 0 0.05" rpy="0 0 0.785"/></joint>
  <joint name="tcp_joint" type="fixed"><parent link="hand"/><child link="tcp"/></joint>
  <joint name="finger_joint" type="prismatic"><parent link="hand"/><child link="finger"/>
    <origin xyz="0 0.02 0.05"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.04" velocity="0.1" effort="5"/></joint>
</robot>
"""
TEST_ARM_LINKS = ("base", "l1", "l2", "spacer", "l3", "l4", "l5", "l6", "hand", "tcp", "finger")
TEST_ARM_OFFSET = ((0.0, 0.01, 0.09), (0.0, 0.1, -0.2))


def _link(name: str, index: int) -> str:
    shape = '<box size="0.06 0.05 0.1"/>' if index % 2 else '<cylinder radius="0.03" length="0.1"/>'
    return (
        f'<link name="{name}"><inertial><origin xyz="0 0.01 0.03" rpy="0.2 0 0"/>'
        '<mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
        f"</inertial><visual><geometry>{shape}</geometry></visual>"
        f"<collision><geometry>{shape}</geometry></collision></link>"
    )


def write_test_arm(folder: Path, text: str = TEST_ARM) -> Path:
    links = "\n  ".join(_link(name, i) for i, name in enumerate(TEST_ARM_LINKS))
    path = folder / "test_arm.urdf"
    path.write_text(text.replace("{links}", links))
    return path


@pytest.fixture(scope="module")
def test_arm(tmp_path_factory: pytest.TempPathFactory) -> UrdfChain:
    return read_chain(
        write_test_arm(tmp_path_factory.mktemp("arm")), "base", "hand", TEST_ARM_OFFSET
    )


def known_chain(name: str) -> UrdfChain:
    """A built-in robot's chain, as its robot file describes it."""
    return robot_chain(load_robot(name))


def _chains(test_arm: UrdfChain) -> Iterator[tuple[str, UrdfChain]]:
    for name in builtin_robots():
        yield name, known_chain(name)
    yield "test_arm", test_arm


def test_the_chains_read_are_the_arms() -> None:
    chain = known_chain("panda")
    assert chain.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert chain.frame_names == (*panda.LINK_NAMES[:8], "panda_grasptarget")
    assert chain.velocity_limits == (2.175,) * 4 + (2.61,) * 3
    assert np.allclose(chain.root_inertial[:3, 3], (0.0, 0.0, panda.BASE_INERTIAL_Z))
    xarm = known_chain("xarm6")
    assert xarm.dof == 6 and xarm.root_link == "world"
    assert np.allclose(xarm.lows[:3], (-2 * math.pi, -2.059, -3.927))
    assert np.allclose(xarm.tool[:3, 3], (0.0, 0.0, 0.155))  # the fixed gripper joint is at 0
    assert known_chain("iiwa").dof == 7


def test_the_test_arm_folds_fixed_joints_and_keeps_any_axis(test_arm: UrdfChain) -> None:
    assert test_arm.joint_names == ("j1", "j2", "j3", "j4", "j5", "j6")
    assert [joint.kind for joint in test_arm.joints].count("continuous") == 1
    assert np.allclose(test_arm.axes[4], (0.6, 0.8, 0.0)) and np.allclose(
        test_arm.axes[5], (0.0, 0.0, -1.0)
    )
    # j3's origin holds the fixed elbow spacer: 0.25 up, pitched 0.2, then 0.05 along that z
    assert np.allclose(
        test_arm.joints[2].origin[:3, 3], (0.05 * math.sin(0.2), 0.0, 0.25 + 0.05 * math.cos(0.2))
    )
    assert test_arm.lows[3] == -math.inf and test_arm.highs[3] == math.inf
    lows, highs = test_arm.sample_bounds()
    assert (lows[3], highs[3]) == (-math.pi, math.pi) and lows[0] == -3.0
    assert test_arm.velocity_limits == (2.5, 2.0, 2.0, 3.0, 3.0, 3.0)
    to_tcp = read_chain(test_arm.urdf, "base", "tcp", TEST_ARM_OFFSET)  # a joint without origin
    assert np.array_equal(to_tcp.tool, test_arm.tool) and to_tcp.frame_names[-1] == "tcp"


def test_generic_fk_is_the_pandas_hard_wired_fk() -> None:
    kinematics = ArmKinematics(known_chain("panda"))
    rng = np.random.default_rng(0)
    base = panda.base_frame(robot_model.arm_mount((0.4, -0.3, 0.8), 0.9))
    configurations = kinematics.random_configurations(rng, 40)
    batch = kinematics.frames_batch(base, configurations)
    for q, frames in zip(configurations, batch, strict=True):
        expected = panda.link_frames(base, q)
        assert np.allclose(frames[:8], expected[:8], rtol=0.0, atol=1e-9)
        assert np.allclose(frames[8], expected[panda.GRASP], rtol=0.0, atol=1e-9)
        assert np.allclose(kinematics.frames(base, q), frames, rtol=0.0, atol=1e-12)
    assert np.allclose(kinematics.tool_frame(base, configurations[0]), batch[0, -1])


def test_fk_matches_pybullets_link_states(test_arm: UrdfChain) -> None:
    """Every chain frame and the tool frame, on random configurations, for the three arms
    and the test arm (whose root inertial frame is rotated and offset)."""
    rng = np.random.default_rng(1)
    for name, chain in _chains(test_arm):
        kinematics = ArmKinematics(chain)
        reference = PyBulletArm(chain)
        try:
            links = {
                p.getJointInfo(reference.body, j, physicsClientId=reference.client)[12].decode(): j
                for j in range(p.getNumJoints(reference.body, physicsClientId=reference.client))
            }
            compared = 0
            for q in kinematics.random_configurations(rng, 12):
                frames = kinematics.frames(reference.base, q)
                assert np.allclose(reference.tool_frame(q), frames[-1], atol=STATE_TOLERANCE), name
                for frame, link in zip(frames[:-1], chain.frame_names[:-1], strict=True):
                    if link in links:  # the root link is PyBullet's base, not a link
                        assert np.allclose(
                            reference.link_frame(links[link]), frame, atol=STATE_TOLERANCE
                        ), (name, link)
                        compared += 1
            assert compared >= 12 * chain.dof, name
        finally:
            reference.close()


def test_base_frames_follow_pybullets_two_conventions(test_arm: UrdfChain) -> None:
    """``getBasePositionAndOrientation`` is the root's inertial frame, ``loadURDF``'s pose the
    root's link frame: both put the base link where PyBullet does."""
    client = p.connect(p.DIRECT)
    try:
        position, orientation = (0.3, -0.2, 0.4), p.getQuaternionFromEuler((0.2, -0.1, 0.7))
        body = p.loadURDF(
            str(test_arm.urdf), position, orientation, useFixedBase=True, physicsClientId=client
        )
        load_pose = np.eye(4)
        load_pose[:3, :3] = np.reshape(p.getMatrixFromQuaternion(orientation), (3, 3))
        load_pose[:3, 3] = position
        com, com_orientation = p.getBasePositionAndOrientation(body, physicsClientId=client)
        body_pose = np.eye(4)
        body_pose[:3, :3] = np.reshape(p.getMatrixFromQuaternion(com_orientation), (3, 3))
        body_pose[:3, 3] = com
        state = p.getLinkState(body, 0, computeForwardKinematics=True, physicsClientId=client)
        expected = np.eye(4)
        expected[:3, :3] = np.reshape(p.getMatrixFromQuaternion(state[5]), (3, 3))
        expected[:3, 3] = state[4]
        assert not np.allclose(body_pose, load_pose, atol=1e-3)  # the trap is really there
        assert np.allclose(test_arm.base_frame(body_pose), expected, atol=STATE_TOLERANCE)
        assert np.allclose(test_arm.base_frame_as_loaded(load_pose), expected, atol=STATE_TOLERANCE)
    finally:
        p.disconnect(client)


def _check_ik(kinematics: ArmKinematics, count: int, seeds_per_target: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    base = np.eye(4)
    targets = kinematics.frames_batch(base, kinematics.random_configurations(rng, count))[:, -1]
    seeds = kinematics.random_configurations(rng, count * seeds_per_target).reshape(
        count, seeds_per_target, kinematics.dof
    )
    result = kinematics.solve_batch(base, targets, seeds, ik.POSITION_TOLERANCE, ik.ANGLE_TOLERANCE)
    # all of them here (measured); one may go either way on another CPU's rounding
    assert result.solved.sum() >= count - 1
    assert np.all(result.q >= kinematics.lows) and np.all(result.q <= kinematics.highs)
    assert np.all(result.attempts >= 1) and np.all(result.attempts <= seeds_per_target)
    for q, target, solved in zip(result.q, targets, result.solved, strict=True):
        reached = kinematics.tool_frame(base, q)
        position = float(np.linalg.norm(reached[:3, 3] - target[:3, 3]))
        cosine = (np.trace(reached[:3, :3].T @ target[:3, :3]) - 1.0) / 2.0
        angle = math.acos(max(-1.0, min(1.0, cosine)))
        inside = position <= ik.POSITION_TOLERANCE and angle <= ik.ANGLE_TOLERANCE
        assert inside == bool(solved)


def test_ik_solves_reachable_targets_within_the_limits(test_arm: UrdfChain) -> None:
    for _, chain in _chains(test_arm):
        _check_ik(ArmKinematics(chain), 30, 20, 2)


def test_restarts_come_from_the_generator_passed_in() -> None:
    kinematics = ArmKinematics(known_chain("xarm6"))
    rng = np.random.default_rng(3)
    q = kinematics.random_configurations(rng, 1)[0]
    target = kinematics.tool_frame(np.eye(4), q)
    middle = (kinematics.sample_lows + kinematics.sample_highs) / 2
    answers = [
        kinematics.solve_with_restarts(
            np.eye(4),
            target,
            middle,
            np.random.default_rng(9),
            10,
            ik.POSITION_TOLERANCE,
            ik.ANGLE_TOLERANCE,
        )
        for _ in range(2)
    ]
    assert answers[0] is not None and answers[1] is not None
    assert np.array_equal(answers[0][0], answers[1][0])
    assert answers[0][1] <= ik.POSITION_TOLERANCE and answers[0][2] <= ik.ANGLE_TOLERANCE
    far = target.copy()
    far[:3, 3] += (5.0, 0.0, 0.0)  # out of reach
    assert (
        kinematics.solve_with_restarts(
            np.eye(4),
            far,
            middle,
            np.random.default_rng(9),
            2,
            ik.POSITION_TOLERANCE,
            ik.ANGLE_TOLERANCE,
        )
        is None
    )


def test_one_seed_solve_stops_at_the_iteration_budget() -> None:
    kinematics = ArmKinematics(known_chain("iiwa"))
    rng = np.random.default_rng(4)
    q = kinematics.random_configurations(rng, 1)[0]
    target = kinematics.tool_frame(np.eye(4), q)
    seed = np.clip(q + 0.2, kinematics.lows, kinematics.highs)
    _, position, angle = kinematics.solve_pose(np.eye(4), target, seed)
    assert position < 1e-4 and angle < 1e-3
    _, one_position, _ = kinematics.solve_pose(np.eye(4), target, seed, iterations=1)
    assert one_position > position


def test_the_compiled_kernels_agree_with_their_source(test_arm: UrdfChain) -> None:
    """As for the Panda's kernels: the same source run by the interpreter gives the same FK
    and IK answers (coverage sees only interpreted code)."""
    kinematics = ArmKinematics(test_arm)
    rng = np.random.default_rng(5)
    configurations = kinematics.random_configurations(rng, 4)
    targets = kinematics.frames_batch(np.eye(4), configurations)[:, -1]
    seeds = kinematics.random_configurations(rng, 8).reshape(4, 2, kinematics.dof)

    def run() -> tuple[np.ndarray, arm_kinematics.IKBatchResult]:
        frames = kinematics.frames_batch(np.eye(4), configurations)
        return frames, kinematics.solve_batch(
            np.eye(4), targets, seeds, ik.POSITION_TOLERANCE, ik.ANGLE_TOLERANCE
        )

    frames, result = run()
    with interpreted((arm_kinematics, dls_kernels)) as count:
        # arm_kinematics' own five, the two shared steps it imports, and those two at home
        assert count == 5 + 2 + 2
        frames_again, result_again = run()
    assert np.allclose(frames, frames_again, rtol=0.0, atol=1e-12)
    assert np.allclose(result.q, result_again.q, atol=1e-9)
    assert np.array_equal(result.solved, result_again.solved)
    assert np.array_equal(result.attempts, result_again.attempts)


def test_the_shared_orientation_error_is_an_axis_times_its_angle() -> None:
    """No turn, a small turn, and half turns (where the rotation's skew part vanishes and
    the axis comes from the diagonal), both compiled and interpreted."""
    small = np.eye(4)
    small[:3, :3] = [
        [1.0, 0.0, 0.0],
        [0.0, math.cos(0.1), -math.sin(0.1)],
        [0.0, math.sin(0.1), math.cos(0.1)],
    ]
    cases = [
        (np.eye(4), (0.0, 0.0, 0.0)),
        (small, (0.1, 0.0, 0.0)),
        (np.diag([1.0, -1.0, -1.0, 1.0]), (math.pi, 0.0, 0.0)),  # half a turn about x
        (np.diag([-1.0, -1.0, 1.0, 1.0]), (0.0, 0.0, math.pi)),  # ... and about z
    ]
    for function in (dls_kernels.orientation_error, dls_kernels.orientation_error.py_func):
        for target, expected in cases:
            out = np.empty(3)
            function(np.eye(4), target, out, np.empty((3, 3)))
            assert np.allclose(np.abs(out), expected, atol=1e-12)


URDF_ERRORS = [
    ({"base": "nowhere"}, "no link named 'nowhere'"),
    ({"tool": "finger"}, "joint 'finger_joint' between 'base' and 'finger' is prismatic"),
    ({"tool": "l5"}, "the chain from 'base' to 'l5' has 5 moving joints (j1, j2, j3, j4, j5)"),
    ({"base": "l3", "tool": "l1"}, "link 'l1' is not below base link 'l3'"),
    ({"replace": ('<axis xyz="0.6 0.8 0"/>', '<axis xyz="0 0 0"/>')}, "joint 'j5' has a zero axis"),
    (
        {"replace": ('lower="-2" upper="2" velocity="2"', 'velocity="2"')},
        "revolute joint 'j2' has no <limit lower= upper=>",
    ),
    (
        {"replace": ('lower="-2.5" upper="2.5"', 'lower="2.5" upper="-2.5"')},
        "joint 'j3' has lower limit 2.5 above upper limit -2.5",
    ),
    (
        {"replace": ('<parent link="l4"/>', '<parent link="ghost"/>')},
        "joint 'j5' names parent link 'ghost', which the file does not declare",
    ),
    (
        {"replace": ('<parent link="world"/>', '<parent link="ghost"/>')},
        "joint 'mount' names parent link 'ghost', which the file does not declare",
    ),
    ({"replace": ('<child link="l2"/>', "")}, "joint 'j2' has no <child link=...>"),
    (
        {"replace": ('name="mount" type="fixed"', 'name="mount" type="revolute"')},
        "base link 'base' moves with joint 'mount' (revolute)",
    ),
    ({"replace": ('xyz="0 0 0.1"/><axis', 'xyz="0 0.1"/><axis')}, "expected 3 numbers"),
    ({"replace": ("</robot>", "")}, "cannot read the chain"),
]


@pytest.mark.parametrize(("change", "message"), URDF_ERRORS)
def test_a_urdf_that_is_not_a_serial_arm_is_refused_naming_the_joint(
    tmp_path: Path, change: dict[str, object], message: str
) -> None:
    text = TEST_ARM
    if "replace" in change:
        old, new = change["replace"]  # type: ignore[misc]
        assert old in text
        text = text.replace(old, new, 1)
    path = write_test_arm(tmp_path, text)
    base, tool = change.get("base", "base"), change.get("tool", "hand")
    assert isinstance(base, str) and isinstance(tool, str)
    with pytest.raises(StalmError) as caught:
        read_chain(path, base, tool)
    assert message in str(caught.value) and str(path) in str(caught.value)
    assert "\n" not in str(caught.value)


def test_a_missing_file_and_an_unknown_robot_are_refused(tmp_path: Path) -> None:
    with pytest.raises(StalmError, match="cannot read the chain"):
        read_chain(tmp_path / "none.urdf", "a", "b")
    with pytest.raises(StalmError, match="ur5"):
        load_robot("ur5")


def test_a_reference_arm_that_cannot_be_built_closes_its_client() -> None:
    """A chain naming a joint its URDF lacks fails the reference while it is being built; the
    PyBullet client it had opened is closed, not leaked."""
    import dataclasses

    import pybullet

    from stalm.motion.ik_reference import PyBulletArm

    chain = known_chain("iiwa")
    renamed = dataclasses.replace(chain.joints[0], name="no_such_joint")
    broken = dataclasses.replace(chain, joints=(renamed, *chain.joints[1:]))
    before = pybullet.connect(pybullet.DIRECT)
    pybullet.disconnect(physicsClientId=before)
    with pytest.raises(KeyError):
        PyBulletArm(broken)
    # the failed build opened the lowest free id (``before``'s again, or the next one)
    for client in (before, before + 1):
        assert not pybullet.getConnectionInfo(physicsClientId=client)["isConnected"], client
