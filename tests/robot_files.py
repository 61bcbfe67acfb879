"""A robot no library ships: a 6-joint arm of boxes, cylinders, a sphere and a capsule with a
two-finger prismatic gripper, written by the tests as a URDF and a robot file beside it.

Some links' inertial frames are moved and turned away from their URDF frames, and some
collision shapes are turned too: PyBullet keeps shapes in the inertial frame, so a sphere model
that ignored either would sit in the wrong place and the tests would see it."""

from __future__ import annotations

from pathlib import Path

import yaml

_LINKS = {
    # name: (collision geometry, collision origin xyz rpy, inertial origin xyz rpy)
    "base": ('<cylinder radius="0.08" length="0.1"/>', "0 0 0.05", "0 0 0", "0 0 0.03", "0 0 0"),
    "link1": (
        '<cylinder radius="0.06" length="0.12"/>',
        "0 0 0.06",
        "0 0 0",
        "0.01 0 0.05",
        "0 0 0.4",
    ),
    "link2": ('<box size="0.08 0.08 0.32"/>', "0 0 0.16", "0 0 0", "0 0.02 0.12", "0.3 0.1 0"),
    "link3": ('<box size="0.06 0.06 0.28"/>', "0 0 0.14", "0 0 0", "0 0 0.1", "0 0 0"),
    "link4": ('<sphere radius="0.05"/>', "0 0 0.05", "0 0 0", "0 0 0.05", "0 0.2 0"),
    "link5": ('<box size="0.05 0.05 0.08"/>', "0 0 0.04", "0 0.3 0", "0 0 0.04", "0 0 0"),
    "link6": (
        '<cylinder radius="0.035" length="0.04"/>',
        "0 0 0.02",
        "1.5708 0 0",
        "0 0 0.02",
        "0 0 0",
    ),
    "hand": ('<box size="0.04 0.16 0.04"/>', "0 0 0.02", "0 0 0", "0 0.01 0.02", "0 0 0"),
    "left_finger": (
        '<box size="0.01 0.01 0.05"/>',
        "0 0.005 0.025",
        "0 0 0",
        "0 0.01 0.02",
        "0 0 0",
    ),
    "right_finger": (
        '<box size="0.01 0.01 0.05"/>',
        "0 -0.005 0.025",
        "0 0 0",
        "0 -0.01 0.02",
        "0 0 0",
    ),
    "tcp": None,
}
_JOINTS = [
    # name, type, parent, child, origin xyz, axis, lower, upper
    ("j1", "revolute", "base", "link1", "0 0 0.1", "0 0 1", -3.0, 3.0),
    ("j2", "revolute", "link1", "link2", "0 0 0.12", "0 1 0", -2.0, 2.0),
    ("j3", "revolute", "link2", "link3", "0 0 0.32", "0 1 0", -2.5, 2.5),
    ("j4", "revolute", "link3", "link4", "0 0 0.28", "0 0 1", -3.0, 3.0),
    ("j5", "revolute", "link4", "link5", "0 0 0.1", "0 1 0", -2.0, 2.0),
    ("j6", "revolute", "link5", "link6", "0 0 0.08", "0 0 1", -3.0, 3.0),
    ("hand_fix", "fixed", "link6", "hand", "0 0 0.04", None, 0.0, 0.0),
    ("finger_left", "prismatic", "hand", "left_finger", "0 0.005 0.04", "0 1 0", 0.0, 0.04),
    ("finger_right", "prismatic", "hand", "right_finger", "0 -0.005 0.04", "0 -1 0", 0.0, 0.04),
    ("tcp_fix", "fixed", "hand", "tcp", "0 0 0.08", None, 0.0, 0.0),
]
TEST_ARM_GAP = 0.09
"""The open fingers' inner faces are 2 x (0.005 + 0.04) apart."""


def _link(name: str) -> str:
    shape = _LINKS[name]
    if shape is None:
        return f'<link name="{name}"/>'
    geometry, xyz, rpy, inertial_xyz, inertial_rpy = shape
    collisions = f'<collision><origin xyz="{xyz}" rpy="{rpy}"/><geometry>{geometry}</geometry>'
    collisions += "</collision>"
    if name == "hand":  # a second element: a camera bump on the back of the hand
        collisions += '<collision><origin xyz="0.03 0 0.02" rpy="0 1.5708 0"/><geometry>'
        collisions += '<cylinder radius="0.015" length="0.03"/></geometry></collision>'
    return (
        f'<link name="{name}"><inertial><origin xyz="{inertial_xyz}" rpy="{inertial_rpy}"/>'
        '<mass value="1.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
        f"</inertial>{collisions}</link>"
    )


def _joint(name: str, kind: str, parent: str, child: str, xyz: str, axis: str | None,
           lower: float, upper: float) -> str:  # fmt: skip
    text = f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
    text += f'<origin xyz="{xyz}" rpy="0 0 0"/>'
    if axis is not None:
        text += f'<axis xyz="{axis}"/>'
        text += f'<limit lower="{lower}" upper="{upper}" effort="50" velocity="2.0"/>'
    return text + "</joint>"


def write_test_arm(folder: Path) -> Path:
    """Write ``boxarm.urdf`` and the robot file ``boxarm.yaml`` naming it into ``folder``;
    the robot file's path."""
    links = "".join(_link(name) for name in _LINKS)
    joints = "".join(_joint(*joint) for joint in _JOINTS)
    (folder / "boxarm.urdf").write_text(
        f'<?xml version="1.0"?><robot name="boxarm">{links}{joints}</robot>', encoding="utf-8"
    )
    robot = {
        "name": "boxarm",
        "urdf": "boxarm.urdf",
        "base_link": "base",
        "tool_link": "tcp",
        "gripper": {
            "finger_joints": {"finger_left": 0.04, "finger_right": 0.04},
            "finger_links": ["left_finger", "right_finger"],
            "opening": 0.085,
        },
        "mount": {"kind": "fixed", "xyz": [0.0, 0.0, 0.7], "yaw": 0.0},
        "carry": [0.0, -0.5, 2.0, 0.0, 1.0, 0.0],
        "acceleration_limits": [5.0] * 6,
    }
    path = folder / "boxarm.yaml"
    path.write_text(yaml.safe_dump(robot), encoding="utf-8")
    return path
