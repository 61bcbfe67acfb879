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


# A second arm, for planning: xArm-sized (0.34 m upper arm, 0.30 m forearm, 0.93 m from the
# shoulder to the grasp frame) so that it reaches counters from stalm's mobile base, made of
# boxes and cylinders only. Its root is a mount plate below the arm's base link, and a camera
# on the hand has a visual and no collision shape: what a URDF made by hand often has.
_Y = "1.5708 0 0"
"""A cylinder's axis turned from z onto y (a joint housing across the link)."""


def _cylinder(radius: float, length: float) -> str:
    return f'<cylinder radius="{radius}" length="{length}"/>'


def _box(x: float, y: float, z: float) -> str:
    return f'<box size="{x} {y} {z}"/>'


_REACHER_LINKS: dict[str, tuple[list[tuple[str, str, str]], float, str]] = {
    # name: ([(collision and visual geometry, origin xyz, origin rpy)], mass (kg), centre of mass)
    "mount_plate": ([(_box(0.12, 0.12, 0.02), "0 0 0.01", "0 0 0")], 1.0, "0 0 0.01"),
    "arm_base": ([(_cylinder(0.06, 0.08), "0 0 0.04", "0 0 0")], 1.5, "0 0 0.04"),
    "shoulder": ([(_cylinder(0.055, 0.12), "0 0 0.06", "0 0 0")], 1.5, "0 0 0.06"),
    "upper_arm": (
        [
            (_cylinder(0.05, 0.11), "0 0 0", _Y),
            (_box(0.07, 0.07, 0.26), "0 0 0.17", "0 0 0"),
            (_cylinder(0.045, 0.1), "0 0 0.34", _Y),
        ],
        2.0,
        "0 0 0.17",
    ),
    "forearm": ([(_box(0.06, 0.06, 0.24), "0 0 0.15", "0 0 0")], 1.2, "0 0 0.15"),
    "wrist_roll": ([(_cylinder(0.04, 0.1), "0 0 0.05", "0 0 0")], 0.6, "0 0 0.05"),
    "wrist_pitch": (
        [
            (_cylinder(0.04, 0.08), "0 0 0", _Y),
            (_box(0.06, 0.06, 0.04), "0 0 0.05", "0 0 0"),
        ],
        0.5,
        "0 0 0.03",
    ),
    "flange": ([(_cylinder(0.035, 0.03), "0 0 0.015", "0 0 0")], 0.2, "0 0 0.015"),
    "hand": ([(_box(0.05, 0.14, 0.04), "0 0 0.02", "0 0 0")], 0.4, "0 0 0.02"),
    "left_finger": (
        [(_box(0.02, 0.012, 0.05), "0 0.006 0.025", "0 0 0")], 0.05, "0 0.006 0.025"
    ),
    "right_finger": (
        [(_box(0.02, 0.012, 0.05), "0 -0.006 0.025", "0 0 0")], 0.05, "0 -0.006 0.025"
    ),
    "camera": ([], 0.05, "0 0 0"),  # a visual only: see _reacher_link
}  # fmt: skip
_REACHER_JOINTS = [
    # name, type, parent, child, origin xyz, axis, lower, upper
    ("plate_fix", "fixed", "mount_plate", "arm_base", "0 0 0.02", None, 0.0, 0.0),
    ("j1", "revolute", "arm_base", "shoulder", "0 0 0.08", "0 0 1", -3.1, 3.1),
    ("j2", "revolute", "shoulder", "upper_arm", "0 0 0.12", "0 1 0", -2.2, 2.2),
    ("j3", "revolute", "upper_arm", "forearm", "0 0 0.34", "0 1 0", -2.7, 2.7),
    ("j4", "revolute", "forearm", "wrist_roll", "0 0 0.3", "0 0 1", -3.1, 3.1),
    ("j5", "revolute", "wrist_roll", "wrist_pitch", "0 0 0.1", "0 1 0", -2.2, 2.2),
    ("j6", "revolute", "wrist_pitch", "flange", "0 0 0.08", "0 0 1", -3.1, 3.1),
    ("hand_fix", "fixed", "flange", "hand", "0 0 0.03", None, 0.0, 0.0),
    ("left_finger_joint", "prismatic", "hand", "left_finger", "0 0 0.04", "0 1 0", 0.0, 0.045),
    ("right_finger_joint", "prismatic", "hand", "right_finger", "0 0 0.04", "0 -1 0", 0.0, 0.045),
    ("camera_fix", "fixed", "hand", "camera", "-0.04 0 0.02", None, 0.0, 0.0),
]
REACHER_GRASP_DEPTH = 0.083
"""The grasp frame on the hand's z axis: between the fingers, 7 mm short of their tips (the
palm's face is at 0.04 m, the tips at 0.09 m), as the Panda's and the xArm's."""
REACHER_CARRY = (0.0, -1.203, -2.266, 1.622, -0.792, -0.287)
"""The reacher's carry configuration, found by a random search (20,000 draws 0.05 rad inside
the joint limits, joint 1 at 0, then a local refinement) minimising how far the moving links'
spheres reach from the base centre at the 0.85 m carry lift, with no two links that are not
neighbours in contact, every sphere below 1.3 m and above 0.65 m: the base's 0.35 m top plus
the 0.3 m the lift may go down from its carry height with the arm folded, so the folded arm
never dips into the base. The upper arm leans back over the base, the forearm hangs down from
the elbow and the hand points down and aside; the moving links' spheres reach 0.235 m from
the base centre (the mount plate's 0.238 m) and span 0.661-1.250 m above the floor."""


def _reacher_link(name: str) -> str:
    shapes, mass, centre = _REACHER_LINKS[name]
    inertia = f"{0.001 * mass:.6f}"  # PyBullet's URDF reader fails on some exponents (5e-05)
    text = (
        f'<link name="{name}"><inertial><origin xyz="{centre}" rpy="0 0 0"/>'
        f'<mass value="{mass}"/><inertia ixx="{inertia}" ixy="0" ixz="0" iyy="{inertia}" '
        f'iyz="0" izz="{inertia}"/></inertial>'
    )
    if name == "camera":
        text += '<visual><geometry><box size="0.02 0.04 0.02"/></geometry></visual>'
    for geometry, xyz, rpy in shapes:
        shape = f'<origin xyz="{xyz}" rpy="{rpy}"/><geometry>{geometry}</geometry>'
        text += f'<visual>{shape}<material name="grey"><color rgba="0.6 0.6 0.65 1"/>'
        text += f"</material></visual><collision>{shape}</collision>"
    return text + "</link>"


def _reacher_joint(name: str, kind: str, parent: str, child: str, xyz: str, axis: str | None,
                   lower: float, upper: float) -> str:  # fmt: skip
    text = f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
    text += f'<origin xyz="{xyz}" rpy="0 0 0"/>'
    if axis is not None:
        velocity = 3.0 if kind == "revolute" else 0.1
        text += f'<axis xyz="{axis}"/><limit lower="{lower}" upper="{upper}" effort="50" '
        text += f'velocity="{velocity}"/>'
    return text + "</joint>"


def reacher_robot() -> dict[str, object]:
    """The reacher's robot file, as data: stalm's mobile base and lift (the xArm 6's mount)."""
    return {
        "name": "reacher",
        "urdf": "reacher.urdf",
        "base_link": "arm_base",
        "tool_link": "hand",
        "tool_offset": {"xyz": [0.0, 0.0, REACHER_GRASP_DEPTH]},
        "gripper": {
            "finger_joints": {"left_finger_joint": 0.043, "right_finger_joint": 0.043},
            "finger_links": ["left_finger", "right_finger"],
            "opening": 0.086,
        },
        "mount": {
            "kind": "mobile",
            "base_radius": 0.3,
            "base_height": 0.35,
            "arm_mount_forward": 0.15,
            "lift_range": [0.55, 1.45],
            "carry_lift": 0.85,
            "lift_speed": 0.1,
            "lift_acceleration": 0.5,
            "base_speed": 1.0,
            "base_acceleration": 1.0,
            "base_turn_rate": 1.5,
            "base_turn_acceleration": 0.8,
        },
        "carry": list(REACHER_CARRY),
        "acceleration_limits": [10.0] * 6,
        "sources": {"carry": "a random search for the most compact fold over the base"},
    }


def write_reacher(folder: Path) -> Path:
    """Write ``reacher.urdf`` and the robot file ``reacher.yaml`` naming it into ``folder``
    (made if missing); the robot file's path."""
    folder.mkdir(parents=True, exist_ok=True)
    links = "".join(_reacher_link(name) for name in _REACHER_LINKS)
    joints = "".join(_reacher_joint(*joint) for joint in _REACHER_JOINTS)
    (folder / "reacher.urdf").write_text(
        f'<?xml version="1.0"?><robot name="reacher">{links}{joints}</robot>', encoding="utf-8"
    )
    path = folder / "reacher.yaml"
    path.write_text(yaml.safe_dump(reacher_robot(), sort_keys=False), encoding="utf-8")
    return path


REACHER_PROBLEM = """\
# Two cans on a table go to the counter, for an arm no library ships.
name: REACH1
description: Two cans on a table go to the counter, for the reacher, an arm the tests write.
horizon: 10
time_budget_s: 120.0
optimal_length: 4
floor: [[-2.0, -2.0], [2.0, 2.0]]
robot:
  base: [0.5, 0.0, 3.141593]
  file: robots/reacher.yaml
walls:
- {name: wall_west, center: [-2.05, 0.0, 1.1], size: [0.1, 4.2, 2.2]}
- {name: wall_east, center: [2.05, 0.0, 1.1], size: [0.1, 4.2, 2.2]}
- {name: wall_south, center: [0.0, -2.05, 1.1], size: [4.2, 0.1, 2.2]}
- {name: wall_north, center: [0.0, 2.05, 1.1], size: [4.2, 0.1, 2.2]}
regions:
- name: counter
  room: kitchen
  center: [-1.7, 0.7]
  yaw: 3.141593
  size: [0.6, 0.9]
  top: 0.95
  usable: [0.4, 0.7]
  base_pose: [-1.05, 0.7, 3.141593]
  color: [0.7, 0.7, 0.66, 1.0]
- name: table
  room: kitchen
  center: [-1.7, -0.8]
  yaw: 3.141593
  size: [0.6, 1.0]
  top: 0.75
  usable: [0.4, 0.8]
  base_pose: [-1.05, -0.8, 3.141593]
  color: [0.52, 0.36, 0.22, 1.0]
objects:
- {name: can1, shape: cylinder, radius: 0.033, height: 0.12, 'on': table, at: [0.0, 0.2]}
- {name: can2, shape: cylinder, radius: 0.033, height: 0.12, 'on': table, at: [0.0, -0.2]}
goal:
- [can1, 'on', counter]
- [can2, 'on', counter]
"""
"""A problem for the reacher: a counter (0.95 m) and a table (0.75 m) in a 4 m room, naming
the robot file by a path relative to the problem file."""


def write_reacher_problem(folder: Path) -> Path:
    """Write the reacher into ``folder/robots`` and :data:`REACHER_PROBLEM` as
    ``folder/reach1.yaml``; the problem file's path."""
    write_reacher(folder / "robots")
    path = folder / "reach1.yaml"
    path.write_text(REACHER_PROBLEM, encoding="utf-8")
    return path
