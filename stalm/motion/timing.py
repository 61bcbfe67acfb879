"""Time-optimal timing of straight moves under velocity and acceleration limits, with TOPP-RA.

Every motion stalm plans is a chain of straight moves: the arm's between joint-space waypoints
(:func:`stalm.motion.arm_motion.interpolate_waypoints`) and the base's between roadmap corners
(:func:`stalm.motion.base_motion.densify`). The collision checks swept exactly those lines, so a
trajectory that rounded a corner would leave the checked path. Each straight move is therefore
timed on its own, from rest to rest: the robot stops at every waypoint, and between two of them
toppra's TOPP-RA finds the fastest timing along the line that keeps every joint within its
limits. toppra enforces the limits at its grid points (its samples of curved paths overshoot by
a fraction of a percent), so moves are timed at :data:`LIMIT_SCALE` of the limits.

toppra (with scipy and matplotlib) takes over a second to import, so it is imported only when a
move is timed. Its solver works on path speeds squared with absolute tolerances: a move
parameterised over [0, 1] that is a fraction of a micro-radian long (a yaw rounding, met on a
P5 plan) leaves it no controllable set, so each move is parameterised over its own time scale.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from stalm.geometry.transforms import wrap_angle
from stalm.motion.base_motion import SE2, BasePath
from stalm.world.robot_limits import BaseLimits, JointLimits

LIMIT_SCALE = 0.98
"""Moves are timed at this fraction of every limit: a margin for the sampled trajectory."""
BISECTION_STEPS = 32
"""Halvings of a move's duration when finding the time a fraction of it is reached: to a
4e9th of it (a nanosecond of a four-second move)."""
SAME_TIME = 1e-9
"""Sample times closer than this (s) are one sample."""


@dataclass(frozen=True)
class StraightMove:
    """A straight move from ``start`` to ``end``, at rest at both, timed by TOPP-RA (no
    trajectory when the two are the same: the move takes no time)."""

    start: tuple[float, ...]
    end: tuple[float, ...]
    duration: float
    trajectory: Any = field(default=None, compare=False, repr=False)

    def state(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities and accelerations (one row per time, clipped to the move)."""
        times = np.clip(np.asarray(times, dtype=float), 0.0, self.duration)
        if self.trajectory is None:
            still = np.tile(np.asarray(self.start, dtype=float), (len(times), 1))
            return still, np.zeros_like(still), np.zeros_like(still)
        return self.trajectory(times), self.trajectory(times, 1), self.trajectory(times, 2)

    def fraction(self, times: np.ndarray) -> np.ndarray:
        """How much of the way (0 to 1) the move has covered at each time."""
        if self.trajectory is None:
            return np.ones(len(np.asarray(times)))
        start, end = np.asarray(self.start), np.asarray(self.end)
        step = end - start
        positions = self.trajectory(np.clip(np.asarray(times, dtype=float), 0, self.duration))
        return np.clip((positions - start) @ step / float(step @ step), 0.0, 1.0)

    def time_at(self, fractions: Sequence[float]) -> np.ndarray:
        """When the move has covered each fraction of the way (bisection: the fraction
        covered never decreases)."""
        wanted = np.asarray(fractions, dtype=float)
        low, high = np.zeros(len(wanted)), np.full(len(wanted), self.duration)
        if self.trajectory is None:
            return high
        for _ in range(BISECTION_STEPS):
            middle = (low + high) / 2
            reached = self.fraction(middle) >= wanted
            high = np.where(reached, middle, high)
            low = np.where(reached, low, middle)
        return high


def time_straight_move(
    start: Sequence[float],
    end: Sequence[float],
    velocity: Sequence[float],
    acceleration: Sequence[float],
) -> StraightMove:
    """The fastest rest-to-rest timing of the straight move from ``start`` to ``end`` with
    every coordinate within :data:`LIMIT_SCALE` of its ``velocity`` and ``acceleration``."""
    first, last = tuple(float(x) for x in start), tuple(float(x) for x in end)
    if first == last:
        return StraightMove(first, last, 0.0)
    import toppra
    import toppra.algorithm
    import toppra.constraint

    v = LIMIT_SCALE * np.asarray(velocity, dtype=float)
    a = LIMIT_SCALE * np.asarray(acceleration, dtype=float)
    # the path parameter runs over the move's own time scale (its time at full speed, or to
    # accelerate over it), so the solver's path speeds are near 1 for a long move or a tiny one
    distance = np.abs(np.subtract(last, first))
    scale = float(np.max(np.maximum(distance / v, np.sqrt(distance / a))))
    path = toppra.SplineInterpolator([0.0, scale], np.array([first, last]))  # two knots: a line
    constraints = [
        toppra.constraint.JointVelocityConstraint(np.column_stack([-v, v])),
        toppra.constraint.JointAccelerationConstraint(np.column_stack([-a, a])),
    ]
    solver = toppra.algorithm.TOPPRA(constraints, path, parametrizer="ParametrizeConstAccel")
    trajectory = solver.compute_trajectory(0.0, 0.0)
    if trajectory is None:  # a straight line under positive box limits is always feasible
        raise RuntimeError(f"TOPP-RA found no timing from {first} to {last}")
    return StraightMove(first, last, float(trajectory.duration), trajectory)


@dataclass(frozen=True, eq=False)
class MotionSamples:
    """A timed motion sampled: one row per time (seconds from the motion's start)."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray


@dataclass(frozen=True)
class TimedMotion:
    """Straight moves one after another, stopping at every waypoint between them."""

    moves: tuple[StraightMove, ...]
    waypoints: tuple[tuple[float, ...], ...]

    @property
    def waypoint_times(self) -> tuple[float, ...]:
        """When the motion reaches each waypoint (the first at 0)."""
        times = [0.0]
        for move in self.moves:
            times.append(times[-1] + move.duration)
        return tuple(times)

    @property
    def duration(self) -> float:
        return self.waypoint_times[-1]

    def time_at(self, move: int, fractions: Sequence[float]) -> np.ndarray:
        """When the motion has covered ``fractions`` of its ``move``-th straight move (a move
        past the last: the motion's end)."""
        if move >= len(self.moves):
            return np.full(len(fractions), self.duration)
        return self.waypoint_times[move] + self.moves[move].time_at(fractions)

    def sample(self, rate: float) -> MotionSamples:
        """The motion at ``rate`` samples a second from its start, at every waypoint and at
        its end (at a waypoint, the move that leaves it)."""
        starts = np.asarray(self.waypoint_times)
        grid = np.arange(math.floor(self.duration * rate + SAME_TIME) + 1) / rate
        times = np.unique(np.concatenate([grid, starts]))
        times = times[np.concatenate([[True], np.diff(times) > SAME_TIME])]
        dimension = len(self.waypoints[0])
        positions = np.empty((len(times), dimension))
        velocities, accelerations = np.empty_like(positions), np.empty_like(positions)
        which = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(self.moves) - 1)
        for index, move in enumerate(self.moves):
            rows = which == index
            if rows.any():
                q, qd, qdd = move.state(times[rows] - starts[index])
                positions[rows], velocities[rows], accelerations[rows] = q, qd, qdd
        if not self.moves:
            positions[:] = self.waypoints[0]
            velocities[:] = accelerations[:] = 0.0
        return MotionSamples(times, positions, velocities, accelerations)


def time_waypoints(waypoints: Sequence[Sequence[float]], limits: JointLimits) -> TimedMotion:
    """Straight moves through ``waypoints`` (configurations in ``limits``' joint order)."""
    points = tuple(tuple(float(x) for x in point) for point in waypoints)
    moves = tuple(
        time_straight_move(a, b, limits.velocity, limits.acceleration)
        for a, b in itertools.pairwise(points)
    )
    return TimedMotion(moves, points)


def base_waypoints(path: BasePath) -> list[SE2]:
    """The corners of ``path`` with the yaw :func:`~stalm.motion.base_motion.densify` gives them:
    the base turns evenly along the whole path, from the first corner's yaw by the shorter way
    to the last's (so the yaw is continuous, and the last may differ from the corner's by a
    turn). A path of no length turns in place."""
    corners = path.corners
    start_yaw = corners[0][2]
    turn = wrap_angle(corners[-1][2] - start_yaw)
    total = path.length
    if total == 0.0:
        first = corners[0]
        return [first] if turn == 0.0 else [first, (first[0], first[1], start_yaw + turn)]
    points: list[SE2] = [corners[0]]
    travelled = 0.0
    for a, b in itertools.pairwise(corners):
        travelled += math.dist(a[:2], b[:2])
        points.append((b[0], b[1], start_yaw + travelled / total * turn))
    return points


def time_base_path(path: BasePath, limits: BaseLimits) -> TimedMotion:
    """Straight moves through :func:`base_waypoints`, with the speed along each line (not
    each axis) within ``limits.speed`` and ``limits.acceleration``.

    Along a line of length L the velocity is the direction u times the path speed, so an
    axis limit of ``speed * |u_axis|`` on x and y bounds the speed itself by ``speed`` (an
    axis that does not move keeps the plain limit; it bounds nothing)."""
    points = base_waypoints(path)
    moves = []
    for a, b in itertools.pairwise(points):
        length = math.dist(a[:2], b[:2])
        share = [abs(b[i] - a[i]) / length if length > 0 and b[i] != a[i] else 1.0 for i in (0, 1)]
        moves.append(
            time_straight_move(
                a,
                b,
                (limits.speed * share[0], limits.speed * share[1], limits.turn_rate),
                (
                    limits.acceleration * share[0],
                    limits.acceleration * share[1],
                    limits.turn_acceleration,
                ),
            )
        )
    return TimedMotion(tuple(moves), tuple(points))
