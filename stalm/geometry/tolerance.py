"""Comparing results across machines: discrete parts exactly, continuous values to a tolerance.

The same seed gives the same result bit for bit on one machine. On another machine the last
bits of continuous values may differ: IK iterates in floating point whose rounding depends on
the compiler's and the CPU's choice of instructions (numba compiles it for the local CPU:
fused multiply-add, vector widths), and glibc picks its ``sin``/``cos``/``atan2``
implementation by CPU features. Such differences are of the order of 1e-12; they stay far
below :data:`CONTINUOUS_TOLERANCE`, but a hash of the values (or a value rounded to a grid,
where it sits next to a grid line) flips.

So results are compared as JSON-like trees: strings, integers, booleans, ``None``, keys and
lengths exactly; floats within an absolute tolerance. :data:`CONTINUOUS_TOLERANCE` is two
quanta of :data:`stalm.world.state.RESOLUTION` (1e-6, the grid every State coordinate is
rounded to): a coordinate that differs by 1e-12 may land one quantum apart.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

CONTINUOUS_TOLERANCE = 2e-6
"""Absolute tolerance (metres, radians, or a unitless float) for values compared across
machines."""


@dataclass(frozen=True)
class Difference:
    """Where two trees first differ: a JSON-pointer-like path and the two values there."""

    path: str
    expected: object
    actual: object

    def __str__(self) -> str:
        return f"{self.path or '/'}: expected {self.expected!r}, got {self.actual!r}"


def first_difference(
    expected: object, actual: object, tolerance: float = CONTINUOUS_TOLERANCE, path: str = ""
) -> Difference | None:
    """The first place (depth first, in order) where ``actual`` is not ``expected``: a type,
    key, length or discrete value that differs, or floats more than ``tolerance`` apart.

    An integer and a float compare as numbers (JSON does not keep the distinction for 3.0);
    booleans compare only with booleans. NaN equals NaN; infinities must match exactly.
    """
    if isinstance(expected, bool) or isinstance(actual, bool):
        same = isinstance(expected, bool) and isinstance(actual, bool) and expected == actual
        return None if same else Difference(path, expected, actual)
    if isinstance(expected, int | float) and isinstance(actual, int | float):
        return None if _close(expected, actual, tolerance) else Difference(path, expected, actual)
    if isinstance(expected, Mapping) and isinstance(actual, Mapping):
        if list(expected) != list(actual) and set(expected) != set(actual):
            missing = sorted(map(str, set(expected) - set(actual)))
            extra = sorted(map(str, set(actual) - set(expected)))
            return Difference(path, f"keys missing: {missing}", f"keys extra: {extra}")
        for key in expected:
            found = first_difference(expected[key], actual[key], tolerance, f"{path}/{key}")
            if found is not None:
                return found
        return None
    if _is_sequence(expected) and _is_sequence(actual):
        assert isinstance(expected, Sequence) and isinstance(actual, Sequence)
        for index, (a, b) in enumerate(zip(expected, actual, strict=False)):
            found = first_difference(a, b, tolerance, f"{path}[{index}]")
            if found is not None:
                return found
        if len(expected) != len(actual):
            return Difference(f"{path}.length", len(expected), len(actual))
        return None
    if type(expected) is not type(actual) or expected != actual:
        return Difference(path, expected, actual)
    return None


def close_enough(expected: object, actual: object, tolerance: float = CONTINUOUS_TOLERANCE) -> bool:
    """Do the two trees agree (see :func:`first_difference`)?"""
    return first_difference(expected, actual, tolerance) is None


def _is_sequence(value: object) -> bool:
    return isinstance(value, list | tuple)


def _close(a: float, b: float, tolerance: float) -> bool:
    if isinstance(a, int) and isinstance(b, int):
        return a == b
    a, b = float(a), float(b)
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= tolerance
