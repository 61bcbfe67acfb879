"""Test double: the last bits of continuous values moved, as another CPU would move them.

:func:`nudged_floats` wraps the functions whose results differ between machines (the compiled
IK, whose code numba builds for the local CPU, the samplers' draws of grasp angles and
placements, the joint-space interpolation and the planar transforms built on ``sin``/``cos``)
so that each float they return is moved by ``size`` (alternately up and down). With ``size``
of about 1e-11 this is what a CPU with other rounding does; a golden case run under it must
make the same decisions. With a size beyond the golden tolerance it must fail.
"""

from __future__ import annotations

import itertools
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import stalm.geometry.transforms as transforms
import stalm.motion.arm_motion as arm_motion
import stalm.motion.grasps as grasps
import stalm.motion.panda as panda
from stalm.world.state import ObjectPose


class _Nudger:
    """Moves floats by ``size``, the sign alternating from call to call (deterministic)."""

    def __init__(self, size: float) -> None:
        self.size = size
        self._signs = itertools.cycle((1.0, -1.0, -1.0, 1.0, 1.0, 1.0, -1.0))
        self.calls = 0

    def value(self, value: Any) -> Any:
        if isinstance(value, float):
            if value == 0.0:  # a constant (a pure yaw's x and y): no CPU rounds it otherwise
                return value
            return value + self.size * next(self._signs)
        if isinstance(value, tuple | list):
            return type(value)(self.value(v) for v in value)
        if isinstance(value, ObjectPose):
            return ObjectPose.make(*(self.value(v) for v in (value.x, value.y, value.z, value.yaw)))
        return value

    def wrap(self, function: Callable[..., Any]) -> Callable[..., Any]:
        def nudged(*args: Any, **kwargs: Any) -> Any:
            self.calls += 1
            return self.value(function(*args, **kwargs))

        nudged.__wrapped__ = function  # type: ignore[attr-defined]
        return nudged


def _rebind_everywhere(original: Callable[..., Any], replacement: Callable[..., Any]) -> list:
    """Point every stalm module's name for ``original`` at ``replacement``; returns the undo."""
    undo = []
    for name, module in list(sys.modules.items()):
        if not (name == "stalm" or name.startswith("stalm.")) or module is None:
            continue
        for attribute, value in list(vars(module).items()):
            if value is original:
                setattr(module, attribute, replacement)
                undo.append((module, attribute, original))
    return undo


NUDGED = (
    (panda, "solve_pose"),
    (grasps, "sample_grasp_angles"),
    (grasps, "draw_placement"),
    (arm_motion, "interpolate"),
    (transforms, "se2_to_world"),
    (transforms, "yaw_quat"),
)
"""The stalm functions whose float results are moved: IK (the joints it returns, and its
errors, which only decide acceptance against a 5 mm / 0.03 rad tolerance), the draws, the
interpolation, the planar transforms."""


@contextmanager
def nudged_floats(size: float = 1e-11) -> Iterator[_Nudger]:
    """Within the block, IK, the samplers' draws, interpolation and planar transforms return
    floats moved by ``size``; yields the nudger (its ``calls`` count proves it was used)."""
    nudger = _Nudger(size)
    undo: list = []
    try:
        for module, attribute in NUDGED:
            original = getattr(module, attribute)
            undo.extend(_rebind_everywhere(original, nudger.wrap(original)))
        yield nudger
    finally:
        for module, attribute, original in reversed(undo):
            setattr(module, attribute, original)
