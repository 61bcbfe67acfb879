"""The steps every damped-least-squares IK here shares, compiled with numba, and when it stops.

The Panda's hard-wired IK and the IK of any arm read from a URDF run the same loop: the
orientation error as a rotation vector, one solve of the damped normal equations, the same
stall rule. Kept in one place so both solvers take the same steps and a fix reaches both.
"""

from __future__ import annotations

import math

import numba
import numpy as np

STALL_STEPS = 25
"""IK gives up after this many steps without improving its error by 1% (a local minimum)."""


@numba.njit(cache=True)
def orientation_error(
    current: np.ndarray, target: np.ndarray, out: np.ndarray, rel: np.ndarray
) -> None:
    """The rotation vector taking ``current`` to ``target`` (their 3x3 parts, world frame):
    ``target @ current.T`` as an axis times its angle, into ``out`` (3); ``rel`` (3x3) is
    work space."""
    for i in range(3):
        for j in range(3):
            rel[i, j] = (
                target[i, 0] * current[j, 0]
                + target[i, 1] * current[j, 1]
                + target[i, 2] * current[j, 2]
            )
    cosine = min(1.0, max(-1.0, (rel[0, 0] + rel[1, 1] + rel[2, 2] - 1.0) / 2.0))
    angle = math.acos(cosine)
    ax, ay, az = rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    if norm > 1e-9:
        scale = angle / norm
        out[0], out[1], out[2] = ax * scale, ay * scale, az * scale
        return
    if angle < 1e-6:
        out[0], out[1], out[2] = 0.0, 0.0, 0.0
        return
    k = 0  # a half turn: the axis from the symmetric part's largest diagonal
    for i in range(3):
        if rel[i, i] > rel[k, k]:
            k = i
    column = math.sqrt(max((rel[k, k] + 1.0) / 2.0, 1e-12))
    for i in range(3):
        value = column if i == k else (rel[i, k] + rel[k, i]) / (4.0 * column)
        out[i] = value * angle


@numba.njit(cache=True)
def solve_spd(
    matrix: np.ndarray, rhs: np.ndarray, out: np.ndarray, lower: np.ndarray, y: np.ndarray
) -> None:
    """``out = matrix^-1 rhs`` for a symmetric positive definite ``matrix`` (Cholesky; ``lower``
    (n x n) and ``y`` (n) are work space)."""
    n = matrix.shape[0]
    for i in range(n):
        for j in range(i + 1):
            total = matrix[i, j]
            for k in range(j):
                total -= lower[i, k] * lower[j, k]
            if i == j:
                lower[i, i] = math.sqrt(max(total, 1e-18))
            else:
                lower[i, j] = total / lower[j, j]
    for i in range(n):
        total = rhs[i]
        for k in range(i):
            total -= lower[i, k] * y[k]
        y[i] = total / lower[i, i]
    for i in range(n - 1, -1, -1):
        total = y[i]
        for k in range(i + 1, n):
            total -= lower[k, i] * out[k]
        out[i] = total / lower[i, i]
