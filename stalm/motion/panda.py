"""The Franka Panda's kinematics without PyBullet: forward kinematics and damped-least-squares IK.

The chain is read from the URDF PyBullet loads (``pybullet_data/franka_panda/panda.urdf``): the
seven revolute joints, the fixed joints to the hand and the grasp target, and the fingers at
their fixed opening. Link frames are the URDF's (PyBullet's ``getLinkState(...)[4:6]``); the
arm's base is placed as PyBullet places a loaded URDF, by its inertial frame, which for
``panda_link0`` sits 0.05 m above the link frame.

Both loops are compiled with numba: one configuration's forward kinematics is a few dozen
4x4 products, and IK iterates it. IK is the damped least squares PyBullet's
``calculateInverseKinematics`` also runs, on the grasp target's position and orientation, with
the joint limits enforced by clamping each step; what PyBullet took about a millisecond for
(Python calls, joint resets and a forward-kinematics check per call), this does in tens of
microseconds, for every user of :func:`stalm.motion.ik.solve_ik` alike.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numba
import numpy as np
import pybullet_data

from stalm.motion.dls_kernels import STALL_STEPS, orientation_error, solve_spd
from stalm.motion.urdf_chain import origin_transform
from stalm.world import robot as robot_model

URDF = Path(pybullet_data.getDataPath()) / "franka_panda" / "panda.urdf"
BASE_INERTIAL_Z = 0.05
"""``panda_link0``'s inertial origin above its link frame: where PyBullet puts the base pose."""
LINK_NAMES = (
    "panda_link0",
    "panda_link1",
    "panda_link2",
    "panda_link3",
    "panda_link4",
    "panda_link5",
    "panda_link6",
    "panda_link7",
    "panda_hand",
    "panda_leftfinger",
    "panda_rightfinger",
    "panda_grasptarget",
)
"""The frames :func:`link_frames` computes, in this order (index 0: the base link)."""
HAND, LEFT_FINGER, RIGHT_FINGER, GRASP = 8, 9, 10, 11


@dataclass(frozen=True)
class PandaChain:
    """Joint origins of the chain, as 4x4 arrays numba can take.

    ``revolute[i]`` is joint i+1's origin in its parent link's frame (each turns about its
    z axis); ``hand``, ``fingers`` and ``grasp`` are the fixed transforms from link 7 to the
    hand, from the hand to each finger (at the gripper's opening) and to the grasp target.
    """

    revolute: np.ndarray
    hand: np.ndarray
    fingers: np.ndarray
    grasp: np.ndarray
    lows: np.ndarray
    highs: np.ndarray
    collision_origins: dict[str, np.ndarray]
    collision_meshes: dict[str, Path]


@cache
def panda_chain() -> PandaChain:
    """The chain read from the URDF (once per process)."""
    root = ElementTree.parse(URDF).getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}

    def origin(joint_name: str) -> np.ndarray:
        node = joints[joint_name].find("origin")
        return origin_transform(
            None if node is None else node.get("xyz"), None if node is None else node.get("rpy")
        )

    revolute = np.stack([origin(f"panda_joint{i}") for i in range(1, 8)])
    hand = origin("panda_joint8") @ origin("panda_hand_joint")
    opening = robot_model.FINGER_OPENING
    fingers = []
    for name, side in (("panda_finger_joint1", 1.0), ("panda_finger_joint2", -1.0)):
        slide = np.eye(4)
        slide[1, 3] = side * opening
        fingers.append(origin(name) @ slide)
    grasp = origin("panda_grasptarget_hand")
    origins: dict[str, np.ndarray] = {}
    meshes: dict[str, Path] = {}
    for link in root.findall("link"):
        collision = link.find("collision")
        if collision is None:
            continue
        node = collision.find("origin")
        origins[str(link.get("name"))] = origin_transform(
            None if node is None else node.get("xyz"), None if node is None else node.get("rpy")
        )
        mesh = collision.find("geometry/mesh")
        assert mesh is not None
        meshes[str(link.get("name"))] = URDF.parent / str(mesh.get("filename")).removeprefix(
            "package://"
        )
    lows = np.array([lo for lo, _ in robot_model.ARM_JOINT_LIMITS])
    highs = np.array([hi for _, hi in robot_model.ARM_JOINT_LIMITS])
    return PandaChain(revolute, hand, np.stack(fingers), grasp, lows, highs, origins, meshes)


def base_frame(mount: robot_model.ArmMount) -> np.ndarray:
    """``panda_link0``'s frame for an arm mounted at ``mount`` (PyBullet's base placement)."""
    c, s = math.cos(mount.yaw), math.sin(mount.yaw)
    frame = np.eye(4)
    frame[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    frame[:3, 3] = (mount.x, mount.y, mount.z - BASE_INERTIAL_Z)
    return frame


@numba.njit(cache=True)
def _mul_rot_z(a: np.ndarray, b: np.ndarray, angle: float, out: np.ndarray) -> None:
    """``out = a @ b @ Rz(angle)`` for 4x4 rigid transforms (no BLAS: numba's matmul needs
    scipy, and for 4x4 the loops are faster anyway)."""
    c, s = math.cos(angle), math.sin(angle)
    for i in range(4):
        r0 = a[i, 0] * b[0, 0] + a[i, 1] * b[1, 0] + a[i, 2] * b[2, 0]
        r1 = a[i, 0] * b[0, 1] + a[i, 1] * b[1, 1] + a[i, 2] * b[2, 1]
        r2 = a[i, 0] * b[0, 2] + a[i, 1] * b[1, 2] + a[i, 2] * b[2, 2]
        r3 = a[i, 0] * b[0, 3] + a[i, 1] * b[1, 3] + a[i, 2] * b[2, 3] + a[i, 3]
        out[i, 0] = r0 * c + r1 * s
        out[i, 1] = -r0 * s + r1 * c
        out[i, 2] = r2
        out[i, 3] = r3
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@numba.njit(cache=True)
def link_frames_into(
    base: np.ndarray,
    q: np.ndarray,
    revolute: np.ndarray,
    hand: np.ndarray,
    fingers: np.ndarray,
    grasp: np.ndarray,
    out: np.ndarray,
) -> None:
    """Every frame of :data:`LINK_NAMES` for joints ``q`` (7) into ``out`` (12 x 4 x 4)."""
    out[0] = base
    for i in range(7):
        _mul_rot_z(out[i], revolute[i], q[i], out[i + 1])
    _mul_rot_z(out[7], hand, 0.0, out[HAND])
    _mul_rot_z(out[HAND], fingers[0], 0.0, out[LEFT_FINGER])
    _mul_rot_z(out[HAND], fingers[1], 0.0, out[RIGHT_FINGER])
    _mul_rot_z(out[HAND], grasp, 0.0, out[GRASP])


def link_frames(base: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The 12 frames of :data:`LINK_NAMES` (world, 4x4) for joints ``q`` on ``base``."""
    chain = panda_chain()
    out = np.empty((len(LINK_NAMES), 4, 4))
    link_frames_into(
        base,
        np.asarray(q, dtype=float),
        chain.revolute,
        chain.hand,
        chain.fingers,
        chain.grasp,
        out,
    )
    return out


@numba.njit(cache=True)
def ik_dls(
    base: np.ndarray,
    target: np.ndarray,
    seed: np.ndarray,
    revolute: np.ndarray,
    hand: np.ndarray,
    fingers: np.ndarray,
    grasp: np.ndarray,
    lows: np.ndarray,
    highs: np.ndarray,
    iterations: int,
    damping: float,
) -> tuple[np.ndarray, float, float]:
    """Joints putting the grasp target at ``target`` (4x4), by damped least squares from
    ``seed``; returns the best joints it met (inside the limits) with their position error
    (m) and orientation error (rad). It stops at 0.01 mm and 0.1 mrad, or once
    :data:`STALL_STEPS` steps improved nothing."""
    q = seed.copy()
    frames = np.empty((12, 4, 4))
    error = np.empty(6)
    jacobian = np.empty((6, 7))
    system = np.empty((6, 6))
    weights = np.empty(6)
    rel = np.empty((3, 3))
    lower = np.empty((6, 6))
    y = np.empty(6)
    best = q.copy()
    best_position, best_angle = 1e9, 1e9
    stalled = 0
    for _ in range(iterations):
        link_frames_into(base, q, revolute, hand, fingers, grasp, frames)
        end = frames[GRASP]
        for k in range(3):
            error[k] = target[k, 3] - end[k, 3]
        orientation_error(end, target, error[3:], rel)
        position = math.sqrt(error[0] ** 2 + error[1] ** 2 + error[2] ** 2)
        angle = math.sqrt(error[3] ** 2 + error[4] ** 2 + error[5] ** 2)
        if position + 0.1 * angle < 0.99 * (best_position + 0.1 * best_angle):
            stalled = 0
        else:
            stalled += 1
        if position + 0.1 * angle < best_position + 0.1 * best_angle:
            best[:] = q
            best_position, best_angle = position, angle
        if (position < 1e-5 and angle < 1e-4) or stalled >= STALL_STEPS:
            break
        for i in range(7):
            frame = frames[i + 1]
            ax, ay, az = frame[0, 2], frame[1, 2], frame[2, 2]
            lx, ly, lz = end[0, 3] - frame[0, 3], end[1, 3] - frame[1, 3], end[2, 3] - frame[2, 3]
            jacobian[0, i] = ay * lz - az * ly
            jacobian[1, i] = az * lx - ax * lz
            jacobian[2, i] = ax * ly - ay * lx
            jacobian[3, i] = ax
            jacobian[4, i] = ay
            jacobian[5, i] = az
        for r in range(6):
            for c in range(6):
                total = 0.0
                for k in range(7):
                    total += jacobian[r, k] * jacobian[c, k]
                system[r, c] = total + (damping * damping if r == c else 0.0)
        solve_spd(system, error, weights, lower, y)
        for i in range(7):
            step = 0.0
            for r in range(6):
                step += jacobian[r, i] * weights[r]
            q[i] = min(highs[i], max(lows[i], q[i] + step))
    return best, best_position, best_angle


def solve_pose(
    base: np.ndarray,
    target: np.ndarray,
    seed: tuple[float, ...],
    iterations: int = 150,
    damping: float = 0.05,
) -> tuple[tuple[float, ...], float, float]:
    """:func:`ik_dls` for one target: the joints (a tuple), position and orientation errors."""
    chain = panda_chain()
    q, position, angle = ik_dls(
        base,
        target,
        np.asarray(seed, dtype=float),
        chain.revolute,
        chain.hand,
        chain.fingers,
        chain.grasp,
        chain.lows,
        chain.highs,
        iterations,
        damping,
    )
    return tuple(float(v) for v in q), float(position), float(angle)
