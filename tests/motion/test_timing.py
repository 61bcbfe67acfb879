"""TOPP-RA timing of straight moves: on the line, from rest to rest, within the limits, and as
fast as the limits allow (checked against the closed-form time of a one-joint move)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stalm.motion.base_motion import BasePath, densify
from stalm.motion.timing import (
    LIMIT_SCALE,
    base_waypoints,
    time_base_path,
    time_straight_move,
    time_waypoints,
)
from stalm.world.robot_limits import BaseLimits, JointLimits

TOLERANCE = 1e-6
"""Relative slack on a limit (float rounding; the moves are timed at 98% of the limits)."""


def _one_joint_time(distance: float, velocity: float, acceleration: float) -> float:
    """The least time of a rest-to-rest move of one joint: a trapezoid, or a triangle when the
    move is too short to reach full speed."""
    if distance >= velocity**2 / acceleration:
        return distance / velocity + velocity / acceleration
    return 2 * math.sqrt(distance / acceleration)


@pytest.mark.parametrize("distance", [0.05, 2.0])
def test_a_one_joint_move_takes_the_least_time_the_limits_allow(distance) -> None:
    move = time_straight_move([0.0], [distance], [1.0], [2.0])
    expected = _one_joint_time(distance, LIMIT_SCALE * 1.0, LIMIT_SCALE * 2.0)
    assert move.duration == pytest.approx(expected, rel=0.01)


def test_a_move_stays_on_its_line_from_rest_to_rest_within_its_limits() -> None:
    start, end = np.array([0.8, 0.0, -1.7, 0.3]), np.array([1.0, 1.2, -0.4, -0.5])
    velocity, acceleration = np.array([0.1, 2.0, 2.0, 2.5]), np.array([0.5, 15.0, 7.5, 10.0])
    move = time_straight_move(start, end, velocity, acceleration)
    times = np.linspace(0, move.duration, 400)
    q, qd, qdd = move.state(times)
    assert q[0] == pytest.approx(start, abs=1e-12) and q[-1] == pytest.approx(end, abs=1e-12)
    assert np.abs(qd[[0, -1]]).max() < 1e-9
    along = (q - start) @ (end - start) / ((end - start) @ (end - start))
    assert np.abs(q - (start + np.outer(along, end - start))).max() < 1e-12
    assert np.all(np.diff(along) >= 0)
    assert np.all(np.abs(qd) <= LIMIT_SCALE * velocity * (1 + TOLERANCE))
    assert np.all(np.abs(qdd) <= LIMIT_SCALE * acceleration * (1 + TOLERANCE))
    # some joint is at its limit most of the way: the timing is not needlessly slow
    assert np.max(np.abs(qd) / velocity) == pytest.approx(LIMIT_SCALE, rel=1e-3)
    fractions = [0.0, 0.25, 0.5, 0.9, 1.0]
    assert move.fraction(move.time_at(fractions)) == pytest.approx(fractions, abs=1e-8)


def test_an_empty_move_takes_no_time() -> None:
    move = time_straight_move([1.0, 2.0], [1.0, 2.0], [1.0, 1.0], [1.0, 1.0])
    assert move.duration == 0.0
    q, qd, _ = move.state(np.array([0.0]))
    assert q.tolist() == [[1.0, 2.0]] and qd.tolist() == [[0.0, 0.0]]
    assert move.time_at([0.5]).tolist() == [0.0]


def test_a_motion_stops_at_every_waypoint_and_samples_them() -> None:
    limits = JointLimits(("a", "b"), (1.0, 1.0), (2.0, 2.0))
    waypoints = [(0.0, 0.0), (1.0, 0.0), (1.0, 0.0), (1.0, -0.5)]
    motion = time_waypoints(waypoints, limits)
    assert len(motion.moves) == 3 and motion.moves[1].duration == 0.0
    samples = motion.sample(50.0)
    assert samples.times[0] == 0.0 and samples.times[-1] == pytest.approx(motion.duration)
    assert np.all(np.diff(samples.times) > 0)
    assert np.diff(samples.times).max() <= 1 / 50 + 1e-12
    for time, waypoint in zip(motion.waypoint_times, waypoints, strict=True):
        row = int(np.argmin(np.abs(samples.times - time)))
        assert samples.times[row] == pytest.approx(time, abs=1e-9)
        assert samples.positions[row] == pytest.approx(waypoint, abs=1e-12)
        assert np.abs(samples.velocities[row]).max() < 1e-9
    assert motion.time_at(2, [1.0])[0] == pytest.approx(motion.duration)


def test_a_motion_of_one_waypoint_stays_put() -> None:
    motion = time_waypoints([(0.3, 0.4)], JointLimits(("a", "b"), (1.0, 1.0), (1.0, 1.0)))
    samples = motion.sample(10.0)
    assert motion.duration == 0.0 and samples.positions.tolist() == [[0.3, 0.4]]


def test_the_base_keeps_its_speed_not_each_axis_within_the_limit() -> None:
    limits = BaseLimits(speed=0.5, acceleration=0.4, turn_rate=1.0, turn_acceleration=1.0)
    path = BasePath(((0.0, 0.0, 0.0), (3.0, 4.0, 0.0), (3.0, 9.0, 0.0)))
    samples = time_base_path(path, limits).sample(100.0)
    speed = np.linalg.norm(samples.velocities[:, :2], axis=1)
    push = np.linalg.norm(samples.accelerations[:, :2], axis=1)
    assert speed.max() <= 0.5 * (1 + TOLERANCE) and push.max() <= 0.4 * (1 + TOLERANCE)
    # along the diagonal the speed itself reaches the limit: each axis alone stays below it
    assert speed.max() == pytest.approx(LIMIT_SCALE * 0.5, rel=1e-3)
    assert np.abs(samples.velocities[:, 0]).max() < 0.5 * 0.61
    assert samples.positions[-1] == pytest.approx([3.0, 9.0, 0.0], abs=1e-12)


def test_the_base_turns_as_densify_turns_it() -> None:
    path = BasePath(((0.0, 0.0, 3.0), (1.0, 0.0, 0.0), (1.0, 2.0, -3.0)))
    corners = base_waypoints(path)
    dense = densify(path, 0.5)
    for corner in corners:  # densify passes through each corner with the same yaw
        assert min(math.dist(corner, point) for point in dense) < 1e-12
    assert corners[-1][2] - corners[0][2] == pytest.approx(math.tau - 6.0)  # the short way
    limits = BaseLimits()
    samples = time_base_path(path, limits).sample(50.0)
    assert np.abs(samples.velocities[:, 2]).max() <= limits.turn_rate * (1 + TOLERANCE)
    assert np.abs(samples.accelerations[:, 2]).max() <= limits.turn_acceleration * (1 + TOLERANCE)


def test_a_base_path_of_no_length_turns_in_place_or_stays() -> None:
    turn = base_waypoints(BasePath(((1.0, 1.0, 0.0), (1.0, 1.0, 1.0))))
    assert turn == [(1.0, 1.0, 0.0), (1.0, 1.0, 1.0)]
    assert base_waypoints(BasePath(((1.0, 1.0, 0.5),))) == [(1.0, 1.0, 0.5)]
    motion = time_base_path(BasePath(((1.0, 1.0, 0.0), (1.0, 1.0, 1.0))), BaseLimits())
    assert motion.duration > 0 and motion.sample(50).positions[-1][2] == pytest.approx(1.0)


@pytest.mark.parametrize("size", [1e-14, 1e-9, 3.07e-7, 1e-5, 1e-3, 1.0, 3.0])
def test_moves_from_tiny_to_long_are_timed(size) -> None:
    """TOPP-RA's solver works on path speeds squared: a move parameterised over [0, 1] that is
    a few tenths of a micro-radian long (a base's yaw rounding, met on P5) left it no
    controllable set; the move's own time scale keeps its numbers near 1."""
    limits = BaseLimits()
    path = BasePath(((-3.95, 3.45, -3.141592), (-3.95, 3.45, -3.141592 - size)))
    samples = time_base_path(path, limits).sample(50.0)
    assert samples.positions[-1][2] == pytest.approx(-3.141592 - size, abs=1e-12)
    assert np.abs(samples.velocities[:, 2]).max() <= limits.turn_rate * (1 + TOLERANCE)
    assert np.abs(samples.accelerations[:, 2]).max() <= limits.turn_acceleration * (1 + TOLERANCE)


def test_random_arm_moves_of_every_scale_keep_their_limits() -> None:
    rng = np.random.default_rng(3)
    velocity = np.array([0.1, 2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
    acceleration = np.array([0.5, 15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
    for _ in range(40):
        start = rng.uniform(-2, 2, 8)
        scale = 10 ** rng.uniform(-9, 0.5, 8) * (rng.random(8) < 0.7)
        end = start + rng.uniform(-1, 1, 8) * scale
        move = time_straight_move(start, end, velocity, acceleration)
        q, qd, qdd = move.state(np.linspace(0, move.duration, 200))
        assert q[-1] == pytest.approx(end, abs=1e-12)
        assert np.all(np.abs(qd) <= LIMIT_SCALE * velocity * (1 + TOLERANCE))
        assert np.all(np.abs(qdd) <= LIMIT_SCALE * acceleration * (1 + TOLERANCE))


def test_an_empty_move_is_always_done() -> None:
    move = time_straight_move([1.0], [1.0], [1.0], [1.0])
    assert move.fraction(np.array([0.0, 1.0])).tolist() == [1.0, 1.0]


def test_a_move_toppra_cannot_time_is_an_error_not_a_silent_jump(monkeypatch) -> None:
    import toppra.algorithm

    def no_timing_double(self, *args, **kwargs):  # a solver that finds nothing
        return None

    monkeypatch.setattr(toppra.algorithm.TOPPRA, "compute_trajectory", no_timing_double)
    with pytest.raises(RuntimeError, match="TOPP-RA found no timing"):
        time_straight_move([0.0], [1.0], [1.0], [1.0])
