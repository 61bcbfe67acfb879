"""Robot files: the shipped robots load and the Panda's equals today's constants; a file
that does not fit its URDF (a missing link, a chain that is no 6- or 7-joint arm, a carry
configuration outside the limits, a missing URDF, a bad mount) is one error naming the field;
reach and the carry footprint are derived from the URDF."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p
import pytest
import yaml

from stalm.errors import StalmError
from stalm.world import robot as panda_robot
from stalm.world import robot_limits
from stalm.world.link_shapes import body_convex_parts, transformed
from stalm.world.robot_description import FixedMount, MobileMount
from stalm.world.robot_facts import robot_facts
from stalm.world.robot_loader import builtin_robots, load_robot, robot_file
from stalm.world.robot_urdf import urdf_body
from tests.robot_files import write_test_arm


def _panda_data() -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(robot_file("panda").read_text(encoding="utf-8"))
    return data


def _write(tmp_path: Path, data: dict[str, Any], name: str = "robot.yaml") -> str:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)


def test_the_shipped_robots_load_with_their_chains() -> None:
    assert builtin_robots() == (
        "iiwa",
        "iiwa_gripper",
        "iiwa_gripper_table",
        "panda",
        "panda_table",
        "xarm6",
        "xarm6_table",
    )
    joints = {name: len(load_robot(name).arm_joints) for name in builtin_robots()}
    assert joints == {
        "iiwa": 7,
        "iiwa_gripper": 7,
        "iiwa_gripper_table": 7,
        "panda": 7,
        "panda_table": 7,
        "xarm6": 6,
        "xarm6_table": 6,
    }
    xarm = load_robot("xarm6")
    assert [joint.name for joint in xarm.arm_joints] == [f"joint{i}" for i in range(1, 7)]
    assert xarm.chain[-1].kind == "fixed" and xarm.chain[-1].child_link == "xarm_gripper_base_link"
    assert isinstance(xarm.spec.mount, MobileMount)  # it rides the Panda's base in P1-P6
    iiwa = load_robot("iiwa")
    assert isinstance(iiwa.spec.mount, FixedMount)
    assert iiwa.spec.gripper is None
    # the file's data-sheet velocities replace the URDF's 10 rad/s placeholders
    assert iiwa.velocity_limits[0] == pytest.approx(math.radians(85), abs=1e-4)
    assert iiwa.chain[0].velocity == 10.0
    gripped = load_robot("iiwa_gripper")
    # the same arm as the iiwa's (its URDF's joints and the file's data-sheet velocities),
    # a gripper on its flange, riding the mobile base
    assert [j.name for j in gripped.arm_joints] == [j.name for j in iiwa.arm_joints]
    assert gripped.joint_limits == iiwa.joint_limits
    assert gripped.velocity_limits == iiwa.velocity_limits
    assert gripped.chain[-1].child_link == "wsg_50_body" and gripped.chain[-1].kind == "fixed"
    assert isinstance(gripped.spec.mount, MobileMount)
    assert gripped.gripper.finger_links == ("wsg_50_finger_left", "wsg_50_finger_right")


def test_the_panda_file_describes_exactly_todays_constants() -> None:
    robot = load_robot("panda")
    spec = robot.spec
    mount = spec.mount
    assert isinstance(mount, MobileMount)
    assert robot.urdf_path.relative_to(robot.urdf_path.parents[1]).as_posix() == (
        robot_limits.ARM_URDF
    )
    assert tuple(joint.name for joint in robot.arm_joints) == robot_limits.ARM_JOINT_NAMES
    assert spec.tool_link == panda_robot.GRASP_FRAME
    assert spec.tool_offset.xyz == (0, 0, 0) and spec.tool_offset.rpy == (0, 0, 0)
    assert spec.carry == panda_robot.CARRY_ARM
    assert robot.joint_limits == panda_robot.ARM_JOINT_LIMITS
    assert spec.gripper is not None
    assert set(spec.gripper.finger_joints.values()) == {panda_robot.FINGER_OPENING}
    assert spec.gripper.opening == panda_robot.GRIPPER_GAP  # what grasps are derived from
    assert (mount.base_radius, mount.base_height, mount.arm_mount_forward) == (
        panda_robot.BASE_RADIUS,
        panda_robot.BASE_HEIGHT,
        panda_robot.ARM_MOUNT_FORWARD,
    )
    assert (mount.lift_range, mount.carry_lift) == (panda_robot.LIFT_RANGE, panda_robot.CARRY_LIFT)
    limits = robot_limits.panda_limits()
    assert (mount.lift_speed, *robot.velocity_limits) == limits.arm.velocity
    assert (mount.lift_acceleration, *robot.acceleration_limits) == limits.arm.acceleration
    assert (
        mount.base_speed,
        mount.base_acceleration,
        mount.base_turn_rate,
        mount.base_turn_acceleration,
    ) == (
        limits.base.speed,
        limits.base.acceleration,
        limits.base.turn_rate,
        limits.base.turn_acceleration,
    )


def test_a_user_file_names_a_urdf_beside_it(tmp_path: Path) -> None:
    data = _panda_data()
    data["urdf"] = str(load_robot("panda").urdf_path)  # an absolute path
    data["name"] = "my_panda"
    loaded = load_robot(_write(tmp_path, data))
    assert loaded.name == "my_panda"
    assert loaded.urdf_sha256 == load_robot("panda").urdf_sha256


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"tool_link": "panda_thumb"}, "tool_link: no link 'panda_thumb' in the URDF (links: "),
        ({"base_link": "panda_link2"}, "tool_link: the chain from 'panda_link2' to"),
        (
            {"base_link": "panda_hand", "tool_link": "panda_link7"},
            "tool_link: 'panda_link7' is not below base_link 'panda_hand'",
        ),
        ({"carry": [0.0, -1.7, 0.0, -3.2, 0.0, 1.5, 0.785]}, "carry[3]: -3.2 is outside joint"),
        ({"carry": [0.0, -1.7, 0.0]}, "carry: 3 values for a chain of 7 joints"),
        ({"urdf": "missing/arm.urdf"}, "urdf: no URDF file"),
        ({"mount": {"kind": "wheeled"}}, "mount: Input tag 'wheeled' found using 'kind'"),
        ({"mount": {"kind": "fixed", "xyz": [0, 0]}}, "mount.fixed.xyz"),
        ({"acceleration_limits": [1.0] * 6}, "acceleration_limits: 6 values for a chain of 7"),
        ({"joint_limits": [[1.0, -1.0]] * 7}, "joint_limits[0]: lower 1.0 is not below upper"),
    ],
)
def test_a_file_that_does_not_fit_its_urdf_names_the_field(
    tmp_path: Path, change: dict[str, Any], message: str
) -> None:
    data = _panda_data() | change
    path = _write(tmp_path, data)
    with pytest.raises(StalmError) as raised:
        load_robot(path)
    assert str(raised.value).startswith(f"{path}: ")
    assert message in str(raised.value)
    assert "\n" not in str(raised.value)


def test_a_mobile_mount_with_a_carry_lift_outside_its_range_is_refused(tmp_path: Path) -> None:
    data = _panda_data()
    data["mount"] = data["mount"] | {"carry_lift": 2.0}
    with pytest.raises(StalmError, match=r"mount\.mobile: carry_lift 2\.0 is outside lift_range"):
        load_robot(_write(tmp_path, data))


def test_a_gripper_said_to_open_wider_than_its_fingers_is_refused(tmp_path: Path) -> None:
    data = _panda_data()
    data["gripper"] = data["gripper"] | {"opening": 0.09}
    with pytest.raises(StalmError, match=r"gripper\.opening: 0\.09 m is wider .* 0\.0778 m apart"):
        load_robot(_write(tmp_path, data))


def test_a_prismatic_joint_in_the_chain_is_no_arm(tmp_path: Path) -> None:
    data = _panda_data() | {"tool_link": "panda_leftfinger"}
    with pytest.raises(StalmError, match=r"'panda_finger_joint1' .* is prismatic"):
        load_robot(_write(tmp_path, data))


def test_no_robot_file_and_no_robot_data_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(StalmError, match="no robot 'xarm': give a robot file or one of iiwa, "):
        load_robot("xarm")
    with pytest.raises(StalmError, match="cannot read robot file"):
        load_robot(str(tmp_path / "none.yaml"))
    with pytest.raises(StalmError, match="not a robot file"):
        load_robot(_write(tmp_path, {"colour": "red"}))
    (tmp_path / "list.yaml").write_text("- 1\n", encoding="utf-8")
    with pytest.raises(StalmError, match="must be a mapping of fields, got list"):
        load_robot(str(tmp_path / "list.yaml"))


def test_reach_and_the_carry_footprint_are_derived() -> None:
    facts = robot_facts(load_robot("panda"), np.random.default_rng(0), samples=500)
    # the shoulder (joint 2) to the grasp target: flange reach 0.858 m plus the hand's 0.1 m
    assert 0.85 < facts.reach < 0.96
    assert facts.finger_gap == pytest.approx(0.0778, abs=5e-4)
    # the hand, folded forward over the mount, sticks out of the 0.3 m disc by 25 mm
    assert facts.carry_radius == pytest.approx(0.325, abs=0.002)
    assert facts.carry_fits is False
    xarm = robot_facts(load_robot("xarm6"), np.random.default_rng(0), samples=500)
    # its carry pose folds it over the base, inside the disc
    assert xarm.carry_radius == pytest.approx(0.229, abs=0.002) and xarm.carry_fits is True
    iiwa = robot_facts(load_robot("iiwa"), np.random.default_rng(0), samples=50)
    assert iiwa.carry_radius is None and iiwa.carry_fits is None  # fixed: no footprint
    assert 0.75 < xarm.reach < 0.95
    again = robot_facts(load_robot("xarm6"), np.random.default_rng(0), samples=500)
    assert again == xarm


def test_the_carry_footprint_is_where_the_simulator_puts_the_arm() -> None:
    # PyBullet places a URDF's root by its inertial frame, and the simulator puts that frame
    # at the mount: the iiwa's link 0 has its inertial origin 0.1 m behind its link frame, so
    # the arm stands 0.1 m ahead of where its link frame alone would put it
    robot = load_robot("iiwa_gripper")
    mount = robot.platform
    with urdf_body(robot.urdf_path) as loaded:
        for name, value in robot.gripper.finger_joints.items():
            index = next(
                i for i in range(len(loaded.links) - 1) if loaded.joint_info(i)[1] == name.encode()
            )
            p.resetJointState(loaded.body, index, value, physicsClientId=loaded.client)
        loaded.set_joints(robot.arm_joints, robot.spec.carry)
        p.resetBasePositionAndOrientation(
            loaded.body,
            [mount.arm_mount_forward, 0, mount.carry_lift],
            [0, 0, 0, 1],
            physicsClientId=loaded.client,
        )
        farthest = max(
            float(
                np.linalg.norm(
                    transformed(loaded.link_frame(loaded.links[name]), points)[:, :2], axis=1
                ).max()
            )
            for name, parts in body_convex_parts(loaded).items()
            for points in parts
        )
    facts = robot_facts(robot, np.random.default_rng(0), samples=10)
    assert facts.carry_radius == pytest.approx(farthest, abs=1e-6)
    assert facts.carry_fits is True  # folded over the base, inside its 0.3 m disc


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text(encoding="utf-8")
    assert old in text
    path.write_text(text.replace(old, new, 1), encoding="utf-8")


def test_what_the_urdf_lacks_the_file_must_give(tmp_path: Path) -> None:
    robot = write_test_arm(tmp_path)
    urdf = tmp_path / "boxarm.urdf"
    _edit(urdf, '<joint name="j1" type="revolute">', '<joint name="j1" type="continuous">')
    _edit(urdf, '<limit lower="-3.0" upper="3.0" effort', "<limit effort")
    with pytest.raises(StalmError, match="joint_limits: joint 'j1' has no limits in the URDF"):
        load_robot(str(robot))
    data = yaml.safe_load(robot.read_text(encoding="utf-8"))
    data["joint_limits"] = [[-3.0, 3.0], [-2.0, 2.0], [-2.5, 2.5], [-3.0, 3.0], [-2.0, 2.0]]
    data["joint_limits"].append([-3.0, 3.0])
    robot.write_text(yaml.safe_dump(data), encoding="utf-8")
    assert load_robot(str(robot)).joint_limits[0] == (-3.0, 3.0)
    _edit(urdf, 'effort="50" velocity="2.0"', 'effort="50" velocity="0"')
    with pytest.raises(StalmError, match="velocity_limits: joint 'j1' has no velocity limit"):
        load_robot(str(robot))
    data["velocity_limits"] = [1.5] * 6
    robot.write_text(yaml.safe_dump(data), encoding="utf-8")
    assert load_robot(str(robot)).velocity_limits == (1.5,) * 6


def test_a_urdf_pybullet_cannot_read_is_named(tmp_path: Path) -> None:
    robot = write_test_arm(tmp_path)
    (tmp_path / "boxarm.urdf").write_text("<robot name='x'><link", encoding="utf-8")
    with pytest.raises(StalmError, match=r"urdf: PyBullet cannot load the URDF '.*boxarm\.urdf'"):
        load_robot(str(robot))


@pytest.mark.parametrize(
    ("gripper", "message"),
    [
        ({"finger_joints": {"thumb": 0.0}}, "gripper.finger_joints: no joint 'thumb' in the URDF"),
        ({"finger_joints": {"j6": 0.0}}, "gripper.finger_joints: 'j6' is a joint of the arm's"),
        (
            {"finger_joints": {"finger_left": 0.07}},
            "gripper.finger_joints.finger_left: 0.07 is outside the joint's limits [0.0, 0.04]",
        ),
        ({"finger_links": ["left_finger", "palm"]}, "gripper.finger_links[1]: no link 'palm'"),
    ],
)
def test_a_gripper_that_does_not_fit_the_urdf_is_named(
    tmp_path: Path, gripper: dict[str, Any], message: str
) -> None:
    robot = write_test_arm(tmp_path)
    data = yaml.safe_load(robot.read_text(encoding="utf-8"))
    data["gripper"] = data["gripper"] | gripper
    robot.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(StalmError) as raised:
        load_robot(str(robot))
    assert str(raised.value).startswith(f"{robot}: {message}")
