"""Evenly spread directions on the unit sphere, for casting rays at a shape or bounding one.

The Fibonacci (golden-angle) spiral puts ``count`` points on the sphere with nearly equal
spacing and no random draw, so what is built from them is the same on every run.
"""

from __future__ import annotations

import math

import numpy as np


def fibonacci_directions(count: int) -> np.ndarray:
    """``count`` unit vectors (count x 3) along the golden-angle spiral, pole to pole."""
    index = np.arange(count) + 0.5
    polar = np.arccos(1.0 - 2.0 * index / count)
    azimuth = math.pi * (1.0 + 5.0**0.5) * index
    return np.stack(
        [np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1
    )
