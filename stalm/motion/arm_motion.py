"""Arm motion by linear interpolation in joint space, swept against the scene.

A configuration is the lift height followed by the seven arm joints. Interpolation steps are
small enough that no point of the arm moves more than about :data:`MAX_CARTESIAN_STEP` between
checks (joint steps of :data:`MAX_JOINT_STEP` rad at under a metre of reach, lift steps of
:data:`MAX_LIFT_STEP` m), less than the smallest object (a 6.6 cm can), so nothing can slip
between two checked configurations.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence

import numpy as np

from stalm.world.scene import Sim

MAX_JOINT_STEP = 0.03
MAX_LIFT_STEP = 0.025
MAX_CARTESIAN_STEP = 0.03

Conf = tuple[float, ...]


def interpolation_steps(start: Sequence[float], end: Sequence[float]) -> int:
    """How many steps :func:`interpolate` takes from ``start`` to ``end``: known from the two
    configurations alone, so a motion's size can be bounded before any of it is made."""
    lift_steps = abs(end[0] - start[0]) / MAX_LIFT_STEP
    joint_steps = max(abs(b - a) for a, b in zip(start[1:], end[1:], strict=True)) / MAX_JOINT_STEP
    return max(1, math.ceil(max(lift_steps, joint_steps)))


def interpolate(start: Sequence[float], end: Sequence[float]) -> list[Conf]:
    """Configurations from ``start`` to ``end`` inclusive (lift first, then 7 joints)."""
    steps = interpolation_steps(start, end)
    # the same IEEE operations as a + (b - a) * i / steps element by element, in one array op
    first, last = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    fractions = np.arange(steps + 1, dtype=float)[:, None]
    dense = first + (last - first) * fractions / steps
    return [tuple(row) for row in dense.tolist()]


def interpolate_waypoints(waypoints: Sequence[Sequence[float]]) -> list[Conf]:
    """Dense configurations through every waypoint in turn."""
    dense: list[Conf] = [tuple(waypoints[0])]
    for a, b in itertools.pairwise(waypoints):
        dense.extend(interpolate(a, b)[1:])
    return dense


def interpolated_length(waypoints: Sequence[Sequence[float]]) -> int:
    """``len(interpolate_waypoints(waypoints))``, counted without making the configurations."""
    return 1 + sum(interpolation_steps(a, b) for a, b in itertools.pairwise(waypoints))


def first_collision(
    sim: Sim, base: tuple[float, float, float], confs: Iterable[Conf], ignore: Iterable[int] = ()
) -> set[int]:
    """Bodies hit at the first colliding configuration (empty if the motion is free)."""
    ignored = set(ignore)
    for conf in confs:
        sim.set_arm(base, conf[0], conf[1:])
        hits = sim.robot_contacts(ignored)
        if hits:
            return hits
    return set()


def sweep(
    sim: Sim, base: tuple[float, float, float], confs: Iterable[Conf], ignore: Iterable[int] = ()
) -> set[int]:
    """Every body hit anywhere along the motion (occlusion predicates need them all)."""
    ignored = set(ignore)
    hits: set[int] = set()
    for conf in confs:
        sim.set_arm(base, conf[0], conf[1:])
        hits |= sim.robot_contacts(ignored)
    return hits
