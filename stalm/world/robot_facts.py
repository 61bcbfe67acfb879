"""Facts derived from a robot's URDF, for a person deciding what the robot can do.

Reach: how far the tool frame gets from the shoulder (the chain's second joint, whose origin
a 6- or 7-joint arm's first joint only turns about), the largest distance over configurations
drawn uniformly inside the joint limits. Carry footprint: with a mobile mount, whether every
link's collision shape stays inside the base's disc in the carry configuration, as driving
needs (the roadmap plans for the disc alone). The gripper's opening as measured. All from
PyBullet, in a client of its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stalm.world.link_shapes import body_convex_parts, transformed
from stalm.world.robot_description import MobileMount, Robot
from stalm.world.robot_urdf import finger_gap, tool_offset_matrix, urdf_body

REACH_SAMPLES = 2000
"""Configurations the reach is the largest over (the maximum of 20,000 is within 1 % of it
for the shipped arms)."""


@dataclass(frozen=True)
class RobotFacts:
    """What :func:`robot_facts` derived."""

    reach: float
    """Largest shoulder-to-tool-frame distance found (m)."""
    reach_samples: int
    carry_radius: float | None
    """Mobile mount: the farthest any link's collision shape reaches from the base's centre
    in the carry configuration (m), seen from above; None for a fixed mount."""
    carry_fits: bool | None
    """Mobile mount: ``carry_radius`` is within the base's radius; None for a fixed mount."""
    finger_gap: float | None
    """The gap between the open fingers' collision geometry (m); None without a gripper."""


def robot_facts(robot: Robot, rng: np.random.Generator, samples: int = REACH_SAMPLES) -> RobotFacts:
    """Reach, carry footprint and finger gap of ``robot`` (see the module's docstring)."""
    joints = robot.arm_joints
    low = np.array([limit[0] for limit in robot.joint_limits])
    high = np.array([limit[1] for limit in robot.joint_limits])
    tool = robot.chain[-1].index
    shoulder = joints[1].index
    offset = tool_offset_matrix(robot.spec)
    with urdf_body(robot.urdf_path) as loaded:
        reach = 0.0
        for q in rng.uniform(low, high, size=(samples, len(joints))):
            loaded.set_joints(joints, q)
            tip = (loaded.link_frame(tool) @ offset)[:3, 3]
            reach = max(reach, float(np.linalg.norm(tip - loaded.link_frame(shoulder)[:3, 3])))
        gap = finger_gap(loaded, robot.spec) if robot.spec.gripper is not None else None
        mount = robot.spec.mount
        radius = None
        if isinstance(mount, MobileMount):
            loaded.set_joints(joints, robot.spec.carry)
            # the simulator puts the root's inertial frame (PyBullet's body pose) at the
            # mount, not the base link's frame: a root whose inertial origin is off its
            # frame (the iiwa's link 0) stands that far from where its frame would
            base = np.linalg.inv(loaded.link_frame(-1) @ loaded.inertial_offset(-1))
            farthest = 0.0
            for name, parts in body_convex_parts(loaded).items():
                frame = base @ loaded.link_frame(loaded.links[name])
                for points in parts:
                    xy = transformed(frame, points)[:, :2]
                    xy[:, 0] += mount.arm_mount_forward
                    farthest = max(farthest, float(np.linalg.norm(xy, axis=1).max()))
            radius = farthest
    fits = None if radius is None else radius <= mount.base_radius  # type: ignore[union-attr]
    return RobotFacts(reach, samples, radius, fits, gap)
