"""Compiled tests between primitive shapes: spheres, oriented boxes and upright cylinders.

Rows of floats, so numba can take many at once: a box row is its centre (3), half extents
(3), rotation (9, row-major, box frame to world) and a body column; an upright cylinder row
its centre x, y, bottom z, top z, radius and a body column. Every test is *conservative*:
"apart" is certain, "touches" may be a near miss (the caller confirms it).
"""

from __future__ import annotations

import math

import numba
import numpy as np

BOX_FIELDS = 16
"""A box row: centre (3), half extents (3), rotation (9, row-major, box frame to world), body
column (1)."""
CYLINDER_FIELDS = 6
"""An upright cylinder row: centre x, y, bottom z, top z, radius, body column."""
SHRINK = 0.0005
"""Metres two boxes may overlap and still be called apart: contact in stalm is penetration
deeper than 1 mm (``PENETRATION_TOLERANCE``), so half of it keeps the test conservative while
an object standing on a counter (touching it, overlapping by nothing) is no candidate."""


@numba.njit(cache=True)
def box_aabb(box: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
    for i in range(3):
        reach = 0.0
        for j in range(3):
            reach += abs(box[6 + 3 * i + j]) * box[3 + j]
        low[i] = box[i] - reach
        high[i] = box[i] + reach


@numba.njit(cache=True)
def sphere_touches_box(centre: np.ndarray, radius: float, box: np.ndarray) -> bool:
    total = 0.0
    for j in range(3):
        # the centre's coordinate along the box's j-th axis (column j of its rotation)
        local = 0.0
        for i in range(3):
            local += (centre[i] - box[i]) * box[6 + 3 * i + j]
        excess = abs(local) - box[3 + j]
        if excess > 0.0:
            total += excess * excess
    return total < radius * radius


@numba.njit(cache=True)
def sphere_touches_cylinder(centre: np.ndarray, radius: float, cylinder: np.ndarray) -> bool:
    radial = math.hypot(centre[0] - cylinder[0], centre[1] - cylinder[1]) - cylinder[4]
    radial = max(radial, 0.0)
    axial = max(cylinder[2] - centre[2], centre[2] - cylinder[3], 0.0)
    return radial * radial + axial * axial < radius * radius


@numba.njit(cache=True)
def cylinder_box(cylinder: np.ndarray, out: np.ndarray) -> None:
    """An upright cylinder's bounding box as a box row (axis-aligned)."""
    out[0] = cylinder[0]
    out[1] = cylinder[1]
    out[2] = (cylinder[2] + cylinder[3]) / 2
    out[3] = cylinder[4]
    out[4] = cylinder[4]
    out[5] = (cylinder[3] - cylinder[2]) / 2
    for k in range(9):
        out[6 + k] = 0.0
    out[6] = 1.0
    out[10] = 1.0
    out[14] = 1.0
    out[15] = cylinder[5]


@numba.njit(cache=True)
def _axis(a: np.ndarray, b: np.ndarray, k: int, out: np.ndarray) -> None:
    """The k-th of the 15 separating-axis candidates of boxes ``a`` and ``b``: their 6 face
    normals, then the 9 cross products of an edge of each."""
    if k < 3:
        for i in range(3):
            out[i] = a[6 + 3 * i + k]
        return
    if k < 6:
        for i in range(3):
            out[i] = b[6 + 3 * i + k - 3]
        return
    j, m = (k - 6) // 3, (k - 6) % 3
    u0, u1, u2 = a[6 + j], a[9 + j], a[12 + j]
    v0, v1, v2 = b[6 + m], b[9 + m], b[12 + m]
    out[0] = u1 * v2 - u2 * v1
    out[1] = u2 * v0 - u0 * v2
    out[2] = u0 * v1 - u1 * v0


@numba.njit(cache=True)
def boxes_may_touch(a: np.ndarray, b: np.ndarray, axis: np.ndarray) -> bool:
    """Separating-axis test of two oriented boxes (15 axes); False only if they are apart or
    overlap by less than :data:`SHRINK` along some axis (``axis``: work space of 3)."""
    for k in range(15):
        _axis(a, b, k, axis)
        norm = math.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
        if norm < 1e-9:
            continue
        distance = 0.0
        for i in range(3):
            distance += (b[i] - a[i]) * axis[i]
        distance = abs(distance) / norm
        reach = 0.0
        for j in range(3):
            along_a = 0.0
            along_b = 0.0
            for i in range(3):
                along_a += a[6 + 3 * i + j] * axis[i]
                along_b += b[6 + 3 * i + j] * axis[i]
            reach += (abs(along_a) * a[3 + j] + abs(along_b) * b[3 + j]) / norm
        if distance > reach - SHRINK:
            return False
    return True


@numba.njit(cache=True)
def place_box(frame: np.ndarray, local: np.ndarray, out: np.ndarray) -> None:
    """A box given in ``frame``'s coordinates (a box row) as a world box row."""
    for i in range(3):
        out[i] = (
            frame[i, 0] * local[0] + frame[i, 1] * local[1] + frame[i, 2] * local[2] + frame[i, 3]
        )
    out[3:6] = local[3:6]
    for i in range(3):
        for j in range(3):
            total = 0.0
            for k in range(3):
                total += frame[i, k] * local[6 + 3 * k + j]
            out[6 + 3 * i + j] = total
    out[15] = local[15]


@numba.njit(cache=True)
def apart(low_a: np.ndarray, high_a: np.ndarray, low_b: np.ndarray, high_b: np.ndarray) -> bool:
    for i in range(3):  # noqa: SIM110 - numba compiles loops, not generators
        if low_a[i] > high_b[i] or high_a[i] < low_b[i]:
            return True
    return False
