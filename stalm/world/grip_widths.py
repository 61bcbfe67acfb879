"""How wide the gripper must open to take each object, and why one it cannot take never moves.

A grasp closes the fingers horizontally (the gripper's closing axis stays level at every
pitch), so what must fit between them is the object's horizontal width across the closing
direction at the narrowest grasp its shape offers: a can's diameter, a grill handle's bar, a
plate's rim, a box's narrower side, a mesh's narrowest support-function width (the width of
its convex hull across a direction: the spread of its vertices' projections). An object wider
than the gripper opens along every closing direction can never be picked: it stays where it
stands, as clutter, and the problem checks that warn of objects that can never move name its
width beside the gripper's opening.
"""

from __future__ import annotations

import math

import numpy as np

from stalm.world.object_spec import GRILL_HANDLE_HALF_HEIGHT, ObjectSpec

CLOSING_DIRECTIONS = 720
"""Horizontal closing directions a mesh's widths are measured along (every quarter degree
over a half turn: the width across a direction and its opposite is one)."""


def hull_widths(points: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """The width of the convex hull of ``points`` (n x 3, the object's frame) across each
    horizontal direction at ``angles`` (radians from the frame's x axis): the spread of the
    points' projections onto it, which is what must fit between fingers closing along it."""
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    projections = points[:, :2] @ directions.T
    widths: np.ndarray = projections.max(axis=0) - projections.min(axis=0)
    return widths


def narrowest_grip(obj: ObjectSpec) -> float:
    """The least opening (m) any grasp of ``obj``'s shape needs."""
    if obj.shape == "mesh":
        angles = np.arange(CLOSING_DIRECTIONS) * (math.pi / CLOSING_DIRECTIONS)
        return float(hull_widths(obj.outline.points, angles).min())
    if obj.shape == "box":
        assert obj.size is not None
        return min(obj.size[0], obj.size[1])
    if obj.shape == "grill":
        return 2 * GRILL_HANDLE_HALF_HEIGHT  # the handle's bar, across its depth
    assert obj.radius is not None and obj.height is not None
    if obj.shape == "disc":
        return obj.height  # a plate is pinched at its rim
    return 2 * obj.radius


def too_wide(obj: ObjectSpec, gap: float) -> str | None:
    """Why no grasp of a gripper opening ``gap`` metres fits ``obj`` (in words), or None."""
    width = narrowest_grip(obj)
    if width <= gap:
        return None
    return (
        f"it is {width:.3g} m across at its narrowest, wider than the gripper opens "
        f"({gap:.3g} m): no grasp fits it"
    )
