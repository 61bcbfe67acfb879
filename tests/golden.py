"""Golden files that hold on any machine: values written out, compared to a tolerance.

A golden file keeps what a run produced as plain JSON values (no hashes): discrete parts
(actions, literals, names, failure kinds, counts) compare exactly, floats within
:data:`~stalm.geometry.tolerance.CONTINUOUS_TOLERANCE`, so a CPU that rounds the last bits of
IK or trigonometry differently still passes while a real change of behaviour fails with the
path of the first difference.

Dense motions are summarised (:func:`plain`): a swept motion keeps its hits, and each segment
its number of configurations and the last one, which is where IK's solutions and the
interpolation's end points show (a segment starts where the one before it ended, at the
standing pose of its action, and the configurations in between follow by linear
interpolation).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from stalm.geometry.tolerance import CONTINUOUS_TOLERANCE, first_difference
from stalm.motion.sweeps import ArmSegment, BaseSegment, SweptMotion

DIGITS = 9
"""Floats are written rounded to this many decimals: 1e-9 is far below the tolerance."""


def plain(value: Any) -> Any:
    """A JSON value of ``value``: dataclasses by field name, sets sorted, motions summarised."""
    if isinstance(value, SweptMotion):
        return {
            "hits": sorted(value.hits),
            "held_reach": plain(value.held_reach),
            "segments": [plain(s) for s in value.segments],
        }
    if isinstance(value, ArmSegment | BaseSegment):
        confs = value.confs if isinstance(value, ArmSegment) else value.waypoints
        return {type(value).__name__: {"n": len(confs), "last": plain(confs[-1])}}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return {type(value).__name__: {k: v for k, v in fields.items() if not k.startswith("_")}}
    if isinstance(value, float | np.floating):
        number = float(value)
        return "nan" if math.isnan(number) else round(number, DIGITS) + 0.0
    if isinstance(value, bool | int | str) or value is None:
        return value
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, dict):
        items = [[plain(k), plain(v)] for k, v in value.items()]
        return sorted(items, key=json.dumps)
    if isinstance(value, set | frozenset):
        return sorted((plain(v) for v in value), key=json.dumps)
    if isinstance(value, tuple | list | np.ndarray):
        return [plain(v) for v in value]
    raise TypeError(f"no golden form for {type(value).__name__}")


INLINE = 110
"""A list or object whose compact JSON is at most this long is written on one line."""


def dumps(golden: Any, indent: str = "") -> str:
    """``golden`` as JSON, keys sorted, small lists and objects on one line (short diffs)."""
    compact = json.dumps(golden, sort_keys=True)
    if len(compact) <= INLINE or not isinstance(golden, dict | list) or not golden:
        return compact
    inner = indent + " "
    if isinstance(golden, dict):
        items = [f"{inner}{json.dumps(k)}: {dumps(golden[k], inner)}" for k in sorted(golden)]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    items = [f"{inner}{dumps(v, inner)}" for v in golden]
    return "[\n" + ",\n".join(items) + "\n" + indent + "]"


def write(path: Path, golden: Any) -> None:
    path.write_text(dumps(golden) + "\n")


def read(path: Path) -> Any:
    return json.loads(path.read_text())


def assert_matches(actual: Any, expected: Any, tolerance: float = CONTINUOUS_TOLERANCE) -> None:
    """Fail naming the first difference (see :func:`stalm.geometry.tolerance.first_difference`);
    ``actual`` is made JSON first, as the file was."""
    actual = json.loads(json.dumps(actual))
    difference = first_difference(expected, actual, tolerance)
    assert difference is None, f"differs from the golden file at {difference}"
