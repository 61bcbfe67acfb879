"""Forward kinematics and damped-least-squares IK of any serial arm read from a URDF.

The generalisation of :mod:`stalm.motion.panda`'s compiled code to a
:class:`~stalm.motion.urdf_chain.UrdfChain`: 6 or 7 joints, each turning about its own unit
axis (not only z), a fixed tool transform at the end. Forward kinematics gives every chain
frame (the base link, each moving joint's child link, the tool frame) for one configuration
or a batch of them. IK is the loop :func:`stalm.motion.panda.ik_dls` runs (the same
orientation error, damped normal equations and clamping to the limits, sharing its steps
through :mod:`stalm.motion.dls_kernels`), with restarts from seeds that callers draw from a
generator they pass in; a batch of targets is solved in one compiled call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from stalm.motion.dls_kernels import STALL_STEPS, orientation_error, solve_spd
from stalm.motion.urdf_chain import UrdfChain

ITERATIONS = 150
DAMPING = 0.05


@numba.njit(cache=True)
def _mul_rot_axis(
    a: np.ndarray, b: np.ndarray, axis: np.ndarray, angle: float, out: np.ndarray
) -> None:
    """``out = a @ b @ R(axis, angle)`` for 4x4 rigid transforms and a unit ``axis``
    (Rodrigues' rotation; loops rather than numba's matmul, which needs scipy)."""
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    x, y, z = axis[0], axis[1], axis[2]
    m00, m01, m02 = t * x * x + c, t * x * y - s * z, t * x * z + s * y
    m10, m11, m12 = t * x * y + s * z, t * y * y + c, t * y * z - s * x
    m20, m21, m22 = t * x * z - s * y, t * y * z + s * x, t * z * z + c
    for i in range(4):
        r0 = a[i, 0] * b[0, 0] + a[i, 1] * b[1, 0] + a[i, 2] * b[2, 0]
        r1 = a[i, 0] * b[0, 1] + a[i, 1] * b[1, 1] + a[i, 2] * b[2, 1]
        r2 = a[i, 0] * b[0, 2] + a[i, 1] * b[1, 2] + a[i, 2] * b[2, 2]
        r3 = a[i, 0] * b[0, 3] + a[i, 1] * b[1, 3] + a[i, 2] * b[2, 3] + a[i, 3]
        out[i, 0] = r0 * m00 + r1 * m10 + r2 * m20
        out[i, 1] = r0 * m01 + r1 * m11 + r2 * m21
        out[i, 2] = r0 * m02 + r1 * m12 + r2 * m22
        out[i, 3] = r3
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@numba.njit(cache=True)
def frames_into(
    base: np.ndarray,
    q: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    tool: np.ndarray,
    out: np.ndarray,
) -> None:
    """Every chain frame for joints ``q`` (n) into ``out`` (n + 2 x 4 x 4): the base, each
    moving joint's child link, the tool frame."""
    n = q.shape[0]
    out[0] = base
    for i in range(n):
        _mul_rot_axis(out[i], origins[i], axes[i], q[i], out[i + 1])
    _mul_rot_axis(out[n], tool, axes[0], 0.0, out[n + 1])


@numba.njit(cache=True)
def frames_batch_into(
    base: np.ndarray,
    qs: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    tool: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`frames_into` for each row of ``qs`` (m x n) into ``out`` (m x n + 2 x 4 x 4)."""
    for k in range(qs.shape[0]):
        frames_into(base, qs[k], origins, axes, tool, out[k])


@numba.njit(cache=True)
def ik_dls(
    base: np.ndarray,
    target: np.ndarray,
    seed: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    tool: np.ndarray,
    lows: np.ndarray,
    highs: np.ndarray,
    iterations: int,
    damping: float,
) -> tuple[np.ndarray, float, float]:
    """Joints putting the tool frame at ``target`` (4x4), by damped least squares from
    ``seed``; the best joints met (inside the limits) with their position error (m) and
    orientation error (rad). It stops at 0.01 mm and 0.1 mrad, or once :data:`STALL_STEPS`
    steps improved nothing: :func:`stalm.motion.panda.ik_dls` for any axes and 6 or 7
    joints."""
    n = seed.shape[0]
    q = seed.copy()
    frames = np.empty((n + 2, 4, 4))
    error = np.empty(6)
    jacobian = np.empty((6, n))
    system = np.empty((6, 6))
    weights = np.empty(6)
    rel = np.empty((3, 3))
    lower = np.empty((6, 6))
    y = np.empty(6)
    best = q.copy()
    best_position, best_angle = 1e9, 1e9
    stalled = 0
    for _ in range(iterations):
        frames_into(base, q, origins, axes, tool, frames)
        end = frames[n + 1]
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
        for i in range(n):
            frame = frames[i + 1]
            local = axes[i]
            ax = frame[0, 0] * local[0] + frame[0, 1] * local[1] + frame[0, 2] * local[2]
            ay = frame[1, 0] * local[0] + frame[1, 1] * local[1] + frame[1, 2] * local[2]
            az = frame[2, 0] * local[0] + frame[2, 1] * local[1] + frame[2, 2] * local[2]
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
                for k in range(n):
                    total += jacobian[r, k] * jacobian[c, k]
                system[r, c] = total + (damping * damping if r == c else 0.0)
        solve_spd(system, error, weights, lower, y)
        for i in range(n):
            step = 0.0
            for r in range(6):
                step += jacobian[r, i] * weights[r]
            q[i] = min(highs[i], max(lows[i], q[i] + step))
    return best, best_position, best_angle


@numba.njit(cache=True)
def ik_batch(
    base: np.ndarray,
    targets: np.ndarray,
    seeds: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    tool: np.ndarray,
    lows: np.ndarray,
    highs: np.ndarray,
    iterations: int,
    damping: float,
    position_tolerance: float,
    angle_tolerance: float,
    out_q: np.ndarray,
    out_error: np.ndarray,
    out_attempts: np.ndarray,
) -> None:
    """For each target (m x 4 x 4), :func:`ik_dls` from its seeds (m x k x n) in order until
    one reaches it within the tolerances: the joints of the best attempt into ``out_q``
    (m x n), its position and orientation errors into ``out_error`` (m x 2), and the attempts
    made into ``out_attempts`` (m)."""
    for t in range(targets.shape[0]):
        best_score = 1e18
        for s in range(seeds.shape[1]):
            q, position, angle = ik_dls(
                base, targets[t], seeds[t, s], origins, axes, tool, lows, highs, iterations, damping
            )
            out_attempts[t] = s + 1
            score = position + 0.1 * angle
            if score < best_score:
                best_score = score
                out_q[t] = q
                out_error[t, 0] = position
                out_error[t, 1] = angle
            if position <= position_tolerance and angle <= angle_tolerance:
                break


@dataclass(frozen=True)
class IKBatchResult:
    """Per target: the best joints found, their errors, whether within the tolerances, and
    the attempts made."""

    q: np.ndarray
    position_error: np.ndarray
    angle_error: np.ndarray
    solved: np.ndarray
    attempts: np.ndarray


class ArmKinematics:
    """A chain's arrays, laid out once for the compiled functions."""

    def __init__(self, chain: UrdfChain) -> None:
        self.chain = chain
        self.origins = np.ascontiguousarray(chain.origins)
        self.axes = np.ascontiguousarray(chain.axes)
        self.tool = np.ascontiguousarray(chain.tool)
        self.lows = chain.lows
        self.highs = chain.highs
        self.sample_lows, self.sample_highs = chain.sample_bounds()

    @property
    def dof(self) -> int:
        return self.chain.dof

    def frames(self, base: np.ndarray, q: np.ndarray) -> np.ndarray:
        """The chain's frames (world, ``dof + 2`` x 4 x 4) for joints ``q`` on ``base``."""
        out = np.empty((self.dof + 2, 4, 4))
        frames_into(
            np.asarray(base, dtype=float),
            np.asarray(q, dtype=float),
            self.origins,
            self.axes,
            self.tool,
            out,
        )
        return out

    def frames_batch(self, base: np.ndarray, qs: np.ndarray) -> np.ndarray:
        """:meth:`frames` for each row of ``qs`` (m x dof): m x (dof + 2) x 4 x 4."""
        configurations = np.ascontiguousarray(qs, dtype=float).reshape(-1, self.dof)
        out = np.empty((len(configurations), self.dof + 2, 4, 4))
        frames_batch_into(
            np.asarray(base, dtype=float), configurations, self.origins, self.axes, self.tool, out
        )
        return out

    def tool_frame(self, base: np.ndarray, q: np.ndarray) -> np.ndarray:
        return self.frames(base, q)[-1]

    def random_configurations(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """``count`` configurations drawn uniformly inside the limits (continuous joints in
        one turn)."""
        return rng.uniform(self.sample_lows, self.sample_highs, (count, self.dof))

    def solve_pose(
        self,
        base: np.ndarray,
        target: np.ndarray,
        seed: np.ndarray,
        iterations: int = ITERATIONS,
        damping: float = DAMPING,
    ) -> tuple[np.ndarray, float, float]:
        """:func:`ik_dls` from one seed: the joints, position and orientation errors."""
        q, position, angle = ik_dls(
            np.asarray(base, dtype=float),
            np.asarray(target, dtype=float),
            np.asarray(seed, dtype=float),
            self.origins,
            self.axes,
            self.tool,
            self.lows,
            self.highs,
            iterations,
            damping,
        )
        return q, float(position), float(angle)

    def solve_batch(
        self,
        base: np.ndarray,
        targets: np.ndarray,
        seeds: np.ndarray,
        position_tolerance: float,
        angle_tolerance: float,
        iterations: int = ITERATIONS,
        damping: float = DAMPING,
    ) -> IKBatchResult:
        """Every target (m x 4 x 4) from its seeds (m x k x dof, tried in order), in one
        compiled call."""
        targets = np.ascontiguousarray(targets, dtype=float).reshape(-1, 4, 4)
        seeds = np.ascontiguousarray(seeds, dtype=float).reshape(len(targets), -1, self.dof)
        out_q = np.empty((len(targets), self.dof))
        out_error = np.empty((len(targets), 2))
        out_attempts = np.zeros(len(targets), dtype=np.int64)
        ik_batch(
            np.asarray(base, dtype=float),
            targets,
            seeds,
            self.origins,
            self.axes,
            self.tool,
            self.lows,
            self.highs,
            iterations,
            damping,
            position_tolerance,
            angle_tolerance,
            out_q,
            out_error,
            out_attempts,
        )
        solved = (out_error[:, 0] <= position_tolerance) & (out_error[:, 1] <= angle_tolerance)
        return IKBatchResult(out_q, out_error[:, 0], out_error[:, 1], solved, out_attempts)

    def solve_with_restarts(
        self,
        base: np.ndarray,
        target: np.ndarray,
        first_seed: np.ndarray,
        rng: np.random.Generator,
        restarts: int,
        position_tolerance: float,
        angle_tolerance: float,
    ) -> tuple[np.ndarray, float, float] | None:
        """IK from ``first_seed`` then up to ``restarts`` random seeds drawn from ``rng``;
        the joints and errors of the first attempt within the tolerances, or None."""
        seeds = np.vstack(
            [np.asarray(first_seed, dtype=float)[None], self.random_configurations(rng, restarts)]
        )
        result = self.solve_batch(
            base, np.asarray(target)[None], seeds[None], position_tolerance, angle_tolerance
        )
        if not result.solved[0]:
            return None
        return result.q[0], float(result.position_error[0]), float(result.angle_error[0])
