"""The kinematic chain of a robot file: what forward kinematics and IK compute for it.

A robot file (:mod:`stalm.world.robot_description`) names the URDF, the base and tool links
and the grasp frame's offset from the tool link; this reads that chain from the URDF
(:func:`~stalm.motion.urdf_chain.read_chain`) and gives it the file's joint and velocity
limits, which win over the URDF's (a URDF's numbers are sometimes placeholders, and the
Panda plans within Franka's datasheet limits, tighter than its URDF's). One robot file is the
one place a robot is described: nothing here restates a link name.
"""

from __future__ import annotations

from dataclasses import replace

from stalm.motion.urdf_chain import UrdfChain, read_chain
from stalm.world.robot_description import Robot


def robot_chain(robot: Robot) -> UrdfChain:
    """``robot``'s arm from its base link to its grasp frame, with the robot file's limits."""
    spec = robot.spec
    chain = read_chain(
        robot.urdf_path,
        spec.base_link,
        spec.tool_link,
        (spec.tool_offset.xyz, spec.tool_offset.rpy),
    )
    joints = tuple(
        replace(joint, lower=lower, upper=upper, velocity=velocity)
        for joint, (lower, upper), velocity in zip(
            chain.joints, robot.joint_limits, robot.velocity_limits, strict=True
        )
    )
    return replace(chain, joints=joints)
