"""PyBullet's own IK (``calculateInverseKinematics``), kept as the reference of the compiled
solver in :mod:`stalm.motion.ik`: ``stalm bench ik`` times both on the same targets and counts
how often each reaches them. No planner calls it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pybullet as p

from stalm.geometry.transforms import (
    Pose3,
    angle_between_rotations,
    matrix_from_quat,
    quat_from_matrix,
)
from stalm.motion.ik import ANGLE_TOLERANCE, POSITION_TOLERANCE, IKSolution
from stalm.motion.urdf_chain import UrdfChain
from stalm.world.scene import Sim

REFINEMENTS = 3
"""IK calls per attempt, each starting where the previous ended (PyBullet's IK is one
damped-least-squares run and often stops short of the target)."""


def pybullet_refine(
    sim: Sim, base: tuple[float, float, float], target: Pose3, lift: float, seed: tuple[float, ...]
) -> IKSolution | None:
    """Up to :data:`REFINEMENTS` IK calls from ``seed``; the solution if FK confirms it."""
    lows = [lo for lo, _ in sim.robot.joint_limits]
    highs = [hi for _, hi in sim.robot.joint_limits]
    joints = sim.bodies.joints
    target_rot = matrix_from_quat(target[1])
    held, held_offset = sim.held, sim.held_yaw_offset
    sim.attach(None)
    try:
        q = seed
        for _ in range(REFINEMENTS):
            sim.set_arm(base, lift, q)
            # plain damped least squares: without null-space terms it converges as often here
            # and twice as fast; joint limits are enforced by the check below
            solution = p.calculateInverseKinematics(
                sim.bodies.arm,
                joints.grasp_link,
                list(target[0]),
                list(target[1]),
                maxNumIterations=60,
                residualThreshold=1e-5,
                physicsClientId=sim.client,
            )
            q = tuple(
                min(hi, max(lo, float(v)))
                for v, lo, hi in zip(solution[: len(joints.arm)], lows, highs, strict=True)
            )
            sim.set_arm(base, lift, q)
            pos, orn = sim.gripper_pose()
            if (
                math.dist(pos, target[0]) <= POSITION_TOLERANCE
                and angle_between_rotations(matrix_from_quat(orn), target_rot) <= ANGLE_TOLERANCE
            ):
                return IKSolution(lift, q)
        return None
    finally:
        sim.attach(held, held_offset)


class PyBulletArm:
    """An arm read as a :class:`~stalm.motion.urdf_chain.UrdfChain`, loaded fixed in its own
    PyBullet client at the world origin: its reference forward kinematics
    (``getLinkState``) and IK (``calculateInverseKinematics``), for any robot the compiled
    :mod:`stalm.motion.arm_kinematics` is compared with. Joints beyond the chain (a gripper's)
    stay at zero."""

    def __init__(self, chain: UrdfChain) -> None:
        self.chain = chain
        self.client = p.connect(p.DIRECT)
        try:
            self._load(chain)
        except BaseException:  # the client is this object's to close, even half built
            p.disconnect(physicsClientId=self.client)
            raise

    def _load(self, chain: UrdfChain) -> None:
        self.body = p.loadURDF(str(chain.urdf), useFixedBase=True, physicsClientId=self.client)
        joints = [
            p.getJointInfo(self.body, j, physicsClientId=self.client)
            for j in range(p.getNumJoints(self.body, physicsClientId=self.client))
        ]
        by_name = {info[1].decode(): info[0] for info in joints}
        self.joint_indices = [by_name[name] for name in chain.joint_names]
        movable = [info[0] for info in joints if info[2] != p.JOINT_FIXED]
        self.ik_positions = [movable.index(index) for index in self.joint_indices]
        """Where each chain joint sits in ``calculateInverseKinematics``'s answer (every
        movable joint of the body, in index order)."""
        by_link = {info[12].decode(): info[0] for info in joints}
        self.tool_index = by_link[chain.tool_link]
        position, orientation = p.getBasePositionAndOrientation(
            self.body, physicsClientId=self.client
        )
        self.base = chain.base_frame(_matrix(position, orientation))
        self.tool_offset = self._tool_offset(by_link)
        """The tool frame in the tool link's frame (the chain's tool transform starts at the
        last moving joint's child link, which may lie before the tool link)."""

    def close(self) -> None:
        p.disconnect(self.client)

    def set_joints(self, q: Sequence[float]) -> None:
        for index, value in zip(self.joint_indices, q, strict=True):
            p.resetJointState(self.body, index, float(value), physicsClientId=self.client)

    def link_frame(self, link_index: int) -> np.ndarray:
        """A link's URDF frame (world, 4x4) as PyBullet computes it."""
        state = p.getLinkState(
            self.body, link_index, computeForwardKinematics=True, physicsClientId=self.client
        )
        return _matrix(state[4], state[5])

    def tool_frame(self, q: Sequence[float]) -> np.ndarray:
        """The tool frame (world, 4x4) for joints ``q``: the tool link's frame, then the
        chain's tool offset."""
        self.set_joints(q)
        return self.link_frame(self.tool_index) @ self.tool_offset

    def _tool_offset(self, by_link: dict[str, int]) -> np.ndarray:
        last_child = self.chain.joints[-1].child
        if last_child == self.chain.tool_link:
            return self.chain.tool
        self.set_joints([0.0] * self.chain.dof)
        last = self.link_frame(by_link[last_child])
        return np.linalg.inv(self.link_frame(self.tool_index)) @ last @ self.chain.tool

    def refine(self, target: np.ndarray, seed: Sequence[float]) -> tuple[float, ...] | None:
        """Up to :data:`REFINEMENTS` IK calls from ``seed`` for the tool frame at ``target``
        (4x4); the joints, clamped to the limits, if
        PyBullet's forward kinematics confirms them within stalm's IK tolerances."""
        link_target = target @ np.linalg.inv(self.tool_offset)
        position = [float(v) for v in link_target[:3, 3]]
        orientation = quat_from_matrix(link_target[:3, :3])
        lows, highs = self.chain.lows, self.chain.highs
        q = tuple(float(v) for v in seed)
        for _ in range(REFINEMENTS):
            self.set_joints(q)
            solution = p.calculateInverseKinematics(
                self.body,
                self.tool_index,
                position,
                list(orientation),
                maxNumIterations=60,
                residualThreshold=1e-5,
                physicsClientId=self.client,
            )
            q = tuple(
                min(float(hi), max(float(lo), float(solution[at])))
                for at, lo, hi in zip(self.ik_positions, lows, highs, strict=True)
            )
            reached = self.tool_frame(q)
            if (
                float(np.linalg.norm(reached[:3, 3] - target[:3, 3])) <= POSITION_TOLERANCE
                and angle_between_rotations(reached[:3, :3], target[:3, :3]) <= ANGLE_TOLERANCE
            ):
                return q
        return None


def _matrix(position: Sequence[float], orientation: Sequence[float]) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3] = matrix_from_quat(tuple(orientation))
    matrix[:3, 3] = position
    return matrix
