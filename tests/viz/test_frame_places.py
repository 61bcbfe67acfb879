"""Where each frame of the animation is in the plan (:func:`plan_motion_places`): on the timed
motions' straight moves, so the page can give it a robot time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stalm.motion.arm_motion import interpolate_waypoints
from stalm.motion.base_motion import BasePath, densify
from stalm.motion.timing import base_waypoints
from stalm.viz.animate import BASE_STEP, _arm_places, _base_places


@pytest.mark.parametrize(
    "corners",
    [
        ((0.0, 0.0, 0.0), (1.3, 0.0, 0.5), (1.3, 2.0, 1.0), (1.3, 2.0, 1.0), (0.2, 2.5, 3.0)),
        ((0.5, 0.5, 0.0), (0.5, 0.5, 2.0)),  # a turn in place
        ((0.5, 0.5, 0.0),),
    ],
)
def test_each_base_frame_lies_where_its_place_says(corners) -> None:
    path = BasePath(corners)
    points = base_waypoints(path)
    dense = densify(path, BASE_STEP)
    places = _base_places(path, BASE_STEP)
    assert len(places) == len(dense) - 1
    for pose, (pair, fraction) in zip(dense[1:], places, strict=True):
        if pair >= len(points) - 1:  # a path of no length: at its end
            assert path.length == 0.0 and fraction == 1.0
            expected = np.array(points[-1])
        else:
            a, b = np.array(points[pair]), np.array(points[pair + 1])
            expected = a + fraction * (b - a)
        assert np.array(pose)[:2] == pytest.approx(expected[:2], abs=1e-12)
        assert math.remainder(pose[2] - expected[2], math.tau) == pytest.approx(0.0, abs=1e-12)


def test_each_arm_frame_lies_where_its_place_says() -> None:
    waypoints = [
        (0.85, 0.0, -1.7, 0.0, -3.0, 0.0, 1.5, 0.785),
        (0.80, 0.0, -1.7, 0.0, -3.0, 0.0, 1.5, 0.785),
        (0.80, 0.0, -1.7, 0.0, -3.0, 0.0, 1.5, 0.785),
        (0.80, 0.4, -0.5, 0.0, -2.8, -1.9, 2.0, 0.05),
    ]
    dense = interpolate_waypoints(waypoints)
    places = _arm_places(waypoints)
    assert len(places) == len(dense) and places[0] == (0, 0.0)
    for conf, (pair, fraction) in zip(dense, places, strict=True):
        a, b = np.array(waypoints[pair]), np.array(waypoints[pair + 1])
        assert np.array(conf) == pytest.approx(a + fraction * (b - a), abs=1e-12)
