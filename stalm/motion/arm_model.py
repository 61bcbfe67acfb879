"""The arm a plan moves, as motion planning needs it: its frames, its IK and its sphere model.

A robot file (:mod:`stalm.world.robot_description`) says what the robot is; this is what the
collision test, IK and the samplers compute with. Two kinds answer the same questions:

- :class:`PandaArm`, the Franka Panda every problem uses by default, runs the compiled code
  of :mod:`stalm.motion.panda` and the sphere model of :mod:`stalm.motion.panda_spheres`, so
  that its plans stay the same to the last bit;
- :class:`UrdfArm`, any other arm of 6 or 7 joints, runs :mod:`stalm.motion.arm_kinematics`
  on the chain its robot file names and the spheres fitted to its URDF
  (:mod:`stalm.motion.sphere_fit_store`). A link off the chain (a gripper's knuckles and
  fingers, held open) rides on the chain frame it hangs from, at the pose the open gripper
  gives it; a link no arm joint moves (a mount plate at the URDF's root, above the base link)
  rides on the base link.

The Panda read as a :class:`UrdfArm` is the reference the tests compare :class:`PandaArm`
with (the same frames to 1e-9 m).

A configuration is ``(lift, joint 1, ..., joint n)`` for every robot: the lift is the arm
mount's height above the floor on the mobile base.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Protocol

import numba
import numpy as np
import pybullet as p

from stalm.motion import panda
from stalm.motion.arm_kinematics import ArmKinematics, frames_into
from stalm.motion.panda_spheres import SphereModel, panda_spheres
from stalm.motion.robot_chain import robot_chain
from stalm.motion.sphere_fit_store import robot_spheres
from stalm.world.robot import ArmMount
from stalm.world.robot_description import Robot, is_builtin_panda
from stalm.world.robot_loader import robot_named
from stalm.world.robot_urdf import urdf_body
from stalm.world.scene import Sim

PANDA_NOMINAL_ARM = (0.0, 0.3, 0.0, -1.8, 0.0, 2.1, 0.785)
"""The Panda's first IK seed: the arm reaching forward at mid height, where most grasps lie."""
PANDA_SHOULDER_ABOVE_MOUNT = 0.333
"""The Panda's shoulder (joint 2) above its mount (m), rounded as its lift heights are
chosen by: the planner's recorded plans depend on this value."""


class ArmModel(Protocol):
    """What motion planning asks of an arm (see the module docstring)."""

    @property
    def robot(self) -> Robot: ...

    @property
    def dof(self) -> int: ...

    @property
    def frame_count(self) -> int:
        """Frames :meth:`frames` computes (index 0: the arm's base link)."""
        ...

    @property
    def grasp_frame(self) -> int:
        """The index of the grasp frame among them."""
        ...

    @property
    def spheres(self) -> SphereModel:
        """Spheres on the frames, each frame's consecutive: they contain the arm's collision
        shapes (gripper included) at every configuration."""
        ...

    @property
    def lows(self) -> np.ndarray: ...

    @property
    def highs(self) -> np.ndarray: ...

    @property
    def nominal_arm(self) -> tuple[float, ...]:
        """IK's first seed."""
        ...

    @property
    def shoulder_above_mount(self) -> float:
        """How far the second joint sits above the mount: lift heights are chosen by it."""
        ...

    def base_frame(self, mount: ArmMount) -> np.ndarray:
        """The arm's base link in the world (4x4) when its mount is at ``mount``."""
        ...

    def frames(self, base: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Every frame (``frame_count`` x 4 x 4) for joints ``q`` on ``base``."""
        ...

    def step_frames(self, stands: np.ndarray, confs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each step (base pose ``stands[k]``, configuration ``confs[k]``): every frame
        (steps x ``frame_count`` x 4 x 4) and the reach line (steps x 4: the mount's x, y,
        the grasp frame's x, y)."""
        ...

    def solve_pose(
        self, base: np.ndarray, target: np.ndarray, seed: tuple[float, ...], iterations: int
    ) -> tuple[tuple[float, ...], float, float]:
        """Damped least squares from ``seed`` toward ``target`` (4x4): the joints, the
        position error (m) and the orientation error (rad)."""
        ...


@numba.njit(cache=True)
def _panda_step_frames(
    stands: np.ndarray,
    confs: np.ndarray,
    mount_forward: float,
    base_inertial_z: float,
    revolute: np.ndarray,
    hand: np.ndarray,
    fingers: np.ndarray,
    grasp: np.ndarray,
    out: np.ndarray,
    reach: np.ndarray,
) -> None:
    """The Panda's frames at each step, computed as the collision kernel always has (the
    same operations in the same order: the same floats)."""
    base = np.eye(4)
    for k in range(confs.shape[0]):
        x, y, yaw = stands[k, 0], stands[k, 1], stands[k, 2]
        c, s = math.cos(yaw), math.sin(yaw)
        base[0, 0], base[0, 1], base[1, 0], base[1, 1] = c, -s, s, c
        base[0, 3] = x + mount_forward * c
        base[1, 3] = y + mount_forward * s
        base[2, 3] = confs[k, 0] - base_inertial_z
        panda.link_frames_into(base, confs[k, 1:], revolute, hand, fingers, grasp, out[k])
        reach[k, 0] = base[0, 3]
        reach[k, 1] = base[1, 3]
        reach[k, 2] = out[k, panda.GRASP, 0, 3]
        reach[k, 3] = out[k, panda.GRASP, 1, 3]


@numba.njit(cache=True)
def _chain_step_frames(
    stands: np.ndarray,
    confs: np.ndarray,
    mount_forward: float,
    mount_to_base: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    tool: np.ndarray,
    out: np.ndarray,
    reach: np.ndarray,
) -> None:
    """Any chain's frames at each step: the mount ``mount_forward`` ahead of the base pose at
    the lift's height, the base link ``mount_to_base`` from it."""
    mount = np.eye(4)
    base = np.empty((4, 4))
    grasp = out.shape[1] - 1
    for k in range(confs.shape[0]):
        x, y, yaw = stands[k, 0], stands[k, 1], stands[k, 2]
        c, s = math.cos(yaw), math.sin(yaw)
        mount[0, 0], mount[0, 1], mount[1, 0], mount[1, 1] = c, -s, s, c
        mount[0, 3] = x + mount_forward * c
        mount[1, 3] = y + mount_forward * s
        mount[2, 3] = confs[k, 0]
        for i in range(4):
            for j in range(4):
                total = 0.0
                for m in range(4):
                    total += mount[i, m] * mount_to_base[m, j]
                base[i, j] = total
        frames_into(base, confs[k, 1:], origins, axes, tool, out[k])
        reach[k, 0] = mount[0, 3]
        reach[k, 1] = mount[1, 3]
        reach[k, 2] = out[k, grasp, 0, 3]
        reach[k, 3] = out[k, grasp, 1, 3]


def _mount_matrix(mount: ArmMount) -> np.ndarray:
    c, s = math.cos(mount.yaw), math.sin(mount.yaw)
    matrix = np.eye(4)
    matrix[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    matrix[:3, 3] = (mount.x, mount.y, mount.z)
    return matrix


@dataclass(frozen=True)
class PandaArm:
    """The Franka Panda on the compiled code its plans were recorded with."""

    robot: Robot
    spheres: SphereModel
    dof: int = 7
    frame_count: int = len(panda.LINK_NAMES)
    grasp_frame: int = panda.GRASP
    nominal_arm: tuple[float, ...] = PANDA_NOMINAL_ARM
    shoulder_above_mount: float = PANDA_SHOULDER_ABOVE_MOUNT

    @property
    def lows(self) -> np.ndarray:
        return panda.panda_chain().lows

    @property
    def highs(self) -> np.ndarray:
        return panda.panda_chain().highs

    def base_frame(self, mount: ArmMount) -> np.ndarray:
        return panda.base_frame(mount)

    def frames(self, base: np.ndarray, q: np.ndarray) -> np.ndarray:
        return panda.link_frames(base, q)

    def step_frames(self, stands: np.ndarray, confs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        chain = panda.panda_chain()
        out = np.empty((len(confs), self.frame_count, 4, 4))
        reach = np.empty((len(confs), 4))
        _panda_step_frames(
            stands,
            confs,
            self.robot.platform.arm_mount_forward,
            panda.BASE_INERTIAL_Z,
            chain.revolute,
            chain.hand,
            chain.fingers,
            chain.grasp,
            out,
            reach,
        )
        return out, reach

    def solve_pose(
        self, base: np.ndarray, target: np.ndarray, seed: tuple[float, ...], iterations: int
    ) -> tuple[tuple[float, ...], float, float]:
        return panda.solve_pose(base, target, seed, iterations)


@dataclass(frozen=True)
class UrdfArm:
    """Any arm of 6 or 7 joints, on :mod:`stalm.motion.arm_kinematics`."""

    robot: Robot
    kinematics: ArmKinematics
    spheres: SphereModel
    mount_to_base: np.ndarray
    """The base link's frame in the mount's: PyBullet puts a loaded URDF's root by its
    inertial frame, which the simulator sets at the mount."""
    nominal_arm: tuple[float, ...]
    shoulder_above_mount: float

    @property
    def dof(self) -> int:
        return self.kinematics.dof

    @property
    def frame_count(self) -> int:
        return self.dof + 2

    @property
    def grasp_frame(self) -> int:
        return self.dof + 1

    @property
    def lows(self) -> np.ndarray:
        return self.kinematics.lows

    @property
    def highs(self) -> np.ndarray:
        return self.kinematics.highs

    def base_frame(self, mount: ArmMount) -> np.ndarray:
        return _mount_matrix(mount) @ self.mount_to_base

    def frames(self, base: np.ndarray, q: np.ndarray) -> np.ndarray:
        return self.kinematics.frames(base, q)

    def step_frames(self, stands: np.ndarray, confs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        kinematics = self.kinematics
        out = np.empty((len(confs), self.frame_count, 4, 4))
        reach = np.empty((len(confs), 4))
        _chain_step_frames(
            np.ascontiguousarray(stands, dtype=float),
            np.ascontiguousarray(confs, dtype=float),
            self.robot.platform.arm_mount_forward,
            self.mount_to_base,
            kinematics.origins,
            kinematics.axes,
            kinematics.tool,
            out,
            reach,
        )
        return out, reach

    def solve_pose(
        self, base: np.ndarray, target: np.ndarray, seed: tuple[float, ...], iterations: int
    ) -> tuple[tuple[float, ...], float, float]:
        q, position, angle = self.kinematics.solve_pose(base, target, np.asarray(seed), iterations)
        return tuple(float(v) for v in q), position, angle


def urdf_arm(robot: Robot) -> UrdfArm:
    """``robot``'s arm on the generic kinematics, its fitted spheres moved onto the chain's
    frames (each link's onto the chain frame it hangs from, the gripper open)."""
    chain = robot_chain(robot)
    kinematics = ArmKinematics(chain)
    fitted, _ = robot_spheres(robot)
    joints = robot.arm_joints
    with urdf_body(robot.urdf_path) as loaded:
        loaded.set_joints(joints, [0.0] * len(joints))
        gripper = robot.spec.gripper
        for name, value in gripper.finger_joints.items() if gripper is not None else ():
            index = next(
                j for j in range(len(loaded.links) - 1) if loaded.joint_info(j)[1].decode() == name
            )
            p.resetJointState(loaded.body, index, value, physicsClientId=loaded.client)
        base_index = loaded.links[robot.spec.base_link]
        chain_links = [base_index, *(joint.index for joint in joints)]
        mount_to_base = chain.base_frame(np.eye(4))
        rows: list[tuple[int, np.ndarray, np.ndarray]] = []
        for link in fitted.links:
            index = loaded.links[link.link]
            ancestor = index
            while ancestor not in chain_links and ancestor != -1:
                ancestor = int(loaded.joint_info(ancestor)[16])
            if ancestor not in chain_links:
                # above the arm's base link (a mount plate at the URDF's root) or beside it:
                # no arm joint moves it, so it rides on the base link where it was loaded
                ancestor = base_index
            frame = chain_links.index(ancestor)
            local = np.linalg.inv(loaded.link_frame(ancestor)) @ loaded.link_frame(index)
            centres = link.centres @ local[:3, :3].T + local[:3, 3]
            rows.append((frame, centres, link.radii))
        zero = np.zeros(len(joints))
        at_zero = kinematics.frames(mount_to_base, zero)
    rows.sort(key=lambda row: row[0])
    spheres = SphereModel(
        np.concatenate([np.full(len(radii), frame) for frame, _, radii in rows]).astype(np.int64),
        np.concatenate([centres for _, centres, _ in rows]),
        np.concatenate([radii for _, _, radii in rows]),
    )
    nominal = robot.spec.ready if robot.spec.ready is not None else robot.spec.carry
    return UrdfArm(
        robot,
        kinematics,
        spheres,
        mount_to_base,
        tuple(float(v) for v in nominal),
        float(at_zero[2][2, 3]),
    )


@cache
def arm_model(robot_source: str) -> ArmModel:
    """The arm model of the robot a problem names (by :func:`robot_named`'s key), built once
    per process: the Panda on its compiled code, any other robot on the generic one."""
    robot = robot_named(robot_source)
    if is_builtin_panda(robot):
        return PandaArm(robot, panda_spheres())
    return urdf_arm(robot)


def arm_of(sim: Sim) -> ArmModel:
    """The arm model of the robot in ``sim``."""
    return arm_model(sim.problem.robot.robot)
