"""Do two footprints on a plane overlap: circles and rotated rectangles (the separating axis
theorem). Pure arithmetic on numbers; :mod:`stalm.world.spec` gives objects their footprints.
"""

from __future__ import annotations

import math

Footprint = tuple[float, float, float, float, float | None]
"""(x, y, yaw, half x, half y) of a rectangle, or (x, y, 0, radius, None) of a circle."""


def corners(u: float, v: float, yaw: float, hx: float, hy: float) -> list[tuple[float, float]]:
    """A rectangle's four corners."""
    c, s = math.cos(yaw), math.sin(yaw)
    return [
        (u + c * du - s * dv, v + s * du + c * dv)
        for du, dv in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))
    ]


def planar_footprints_overlap(a: Footprint, b: Footprint, slack: float) -> bool:
    """Do footprints ``a`` and ``b`` share more than ``slack`` metres?"""
    ua, va, ya, ra, ha = a
    ub, vb, yb, rb, hb = b
    if ha is None and hb is None:
        return math.dist((ua, va), (ub, vb)) < ra + rb - slack
    if ha is None or hb is None:  # a rectangle and a circle
        (cu, cv, cr), (u, v, yaw, hx, hy) = (
            ((ua, va, ra), (ub, vb, yb, rb, hb))
            if ha is None
            else ((ub, vb, rb), (ua, va, ya, ra, ha))
        )
        assert hy is not None
        c, s = math.cos(yaw), math.sin(yaw)
        du, dv = cu - u, cv - v
        lu, lv = c * du + s * dv, -s * du + c * dv  # circle centre in the rectangle's frame
        nearest = (max(-hx, min(hx, lu)), max(-hy, min(hy, lv)))
        return math.dist((lu, lv), nearest) < cr - slack
    first, second = corners(ua, va, ya, ra, ha), corners(ub, vb, yb, rb, hb)
    for yaw in (ya, ya + math.pi / 2, yb, yb + math.pi / 2):  # separating axis theorem
        axis = (math.cos(yaw), math.sin(yaw))
        pa = [x * axis[0] + y * axis[1] for x, y in first]
        pb = [x * axis[0] + y * axis[1] for x, y in second]
        if min(pa) >= max(pb) - slack or min(pb) >= max(pa) - slack:
            return False
    return True


def rotated_half_extent(hx: float, hy: float, yaw: float) -> tuple[float, float]:
    """Half extents along x and y of a rectangle of half extents (hx, hy) turned by ``yaw``."""
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    return (c * hx + s * hy, s * hx + c * hy)
