"""The Fibonacci directions are unit vectors spread over the whole sphere."""

from __future__ import annotations

import numpy as np

from stalm.geometry.sphere_points import fibonacci_directions


def test_fibonacci_directions_are_unit_vectors_covering_the_sphere() -> None:
    directions = fibonacci_directions(500)
    assert directions.shape == (500, 3)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, atol=1e-12)
    # every direction of a coarse probe set has one of them within 0.15 rad
    probes = fibonacci_directions(37) @ np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]])
    nearest = np.arccos(np.clip((probes @ directions.T).max(axis=1), -1.0, 1.0))
    assert nearest.max() < 0.15
    assert abs(directions.mean(axis=0)).max() < 0.01
