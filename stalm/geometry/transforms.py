"""Rigid transforms in SE(2) and SE(3) as plain numpy, with quaternions in (x, y, z, w) order.

PyBullet uses (x, y, z, w) quaternions; keeping the same order here means poses pass between
the pure geometry and the simulator without reshuffling. Nothing here imports pybullet.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

Vec = NDArray[np.float64]
Quat = tuple[float, float, float, float]
Pose3 = tuple[tuple[float, float, float], Quat]


def wrap_angle(angle: float) -> float:
    """Map an angle to [-pi, pi) so yaw comparisons and interpolation take the short way."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def yaw_quat(yaw: float) -> Quat:
    """Quaternion of a rotation about +z by ``yaw``."""
    half = 0.5 * yaw
    return (0.0, 0.0, math.sin(half), math.cos(half))


def quat_yaw(quat: Sequence[float]) -> float:
    """Yaw of a quaternion whose rotation is (mostly) about +z."""
    x, y, z, w = quat
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quat_from_matrix(rot: Vec) -> Quat:
    """Quaternion (x, y, z, w) of a 3x3 rotation matrix (Shepperd's method, numerically safe)."""
    m = rot
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0.0:
        s = math.sqrt(trace + 1.0) * 2.0
        w = 0.25 * s
        x = (m[2, 1] - m[1, 2]) / s
        y = (m[0, 2] - m[2, 0]) / s
        z = (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2.0
        w = (m[2, 1] - m[1, 2]) / s
        x = 0.25 * s
        y = (m[0, 1] + m[1, 0]) / s
        z = (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2.0
        w = (m[0, 2] - m[2, 0]) / s
        x = (m[0, 1] + m[1, 0]) / s
        y = 0.25 * s
        z = (m[1, 2] + m[2, 1]) / s
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2.0
        w = (m[1, 0] - m[0, 1]) / s
        x = (m[0, 2] + m[2, 0]) / s
        y = (m[1, 2] + m[2, 1]) / s
        z = 0.25 * s
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return (x / norm, y / norm, z / norm, w / norm)


def matrix_from_quat(quat: Sequence[float]) -> Vec:
    """3x3 rotation matrix of a quaternion (x, y, z, w)."""
    x, y, z, w = quat
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def pose_matrix(pose: Pose3) -> Vec:
    """4x4 homogeneous matrix of a (position, quaternion) pose."""
    mat = np.eye(4)
    mat[:3, :3] = matrix_from_quat(pose[1])
    mat[:3, 3] = pose[0]
    return mat


def matrix_pose(mat: Vec) -> Pose3:
    """(position, quaternion) pose of a 4x4 homogeneous matrix."""
    pos = mat[:3, 3]
    return (float(pos[0]), float(pos[1]), float(pos[2])), quat_from_matrix(mat[:3, :3])


def compose(a: Pose3, b: Pose3) -> Pose3:
    """The pose ``a * b``: ``b`` expressed in the frame ``a``."""
    return matrix_pose(pose_matrix(a) @ pose_matrix(b))


def invert(pose: Pose3) -> Pose3:
    """The inverse transform of ``pose``."""
    return matrix_pose(np.asarray(np.linalg.inv(pose_matrix(pose)), dtype=np.float64))


def se2_to_local(frame: Sequence[float], x: float, y: float) -> tuple[float, float]:
    """Coordinates of the world point (x, y) in the SE(2) frame (fx, fy, fyaw)."""
    fx, fy, fyaw = frame
    dx, dy = x - fx, y - fy
    c, s = math.cos(fyaw), math.sin(fyaw)
    return c * dx + s * dy, -s * dx + c * dy


def se2_to_world(frame: Sequence[float], u: float, v: float) -> tuple[float, float]:
    """World coordinates of the point (u, v) given in the SE(2) frame (fx, fy, fyaw)."""
    fx, fy, fyaw = frame
    c, s = math.cos(fyaw), math.sin(fyaw)
    return fx + c * u - s * v, fy + s * u + c * v


def gripper_rotation(approach_yaw: float, pitch: float) -> Vec:
    """Rotation of a gripper whose approach axis (+z) points along ``approach_yaw``, tilted
    down by ``pitch``, with the fingers closing horizontally (+y stays level).

    This is the paper's gripper orientation (pitch phi, yaw chi) made concrete: pitch 0 is a
    horizontal approach, pitch 45 degrees reaches down at 45 degrees.
    """
    cy, sy = math.cos(approach_yaw), math.sin(approach_yaw)
    cp, sp = math.cos(pitch), math.sin(pitch)
    z_axis = np.array([cy * cp, sy * cp, -sp])
    y_axis = np.array([-sy, cy, 0.0])
    x_axis = np.cross(y_axis, z_axis)
    return np.column_stack([x_axis, y_axis, z_axis])


def angle_between_rotations(a: Vec, b: Vec) -> float:
    """Geodesic angle between two rotation matrices."""
    cos = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(math.acos(max(-1.0, min(1.0, cos))))
