"""The static scene of a generated problem: the kitchen and hall of P1-P6, varied by a seed.

The template (``kitchen_hall.yaml`` beside this module) is P2's scene: the room walls, the
divider with its doorway, seven regions along the walls and in the hall, the kitchen door.
A generated scene keeps the kitchen as it is (its counters stand against the west wall, in
the order of P1-P6) and moves the two hall tables, which stand free, by up to
:data:`HALL_SHIFT` along the hall's walls, their standing poses with them. ``trap`` puts P5's
walled counter where the template says (a grill fits only at its open front); ``door=False``
leaves the doorway open, with no door to open.
"""

from __future__ import annotations

import copy
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from stalm.errors import StalmError

TEMPLATE = Path(__file__).with_name("kitchen_hall.yaml")
LAYOUTS = ("kitchen-hall",)
"""The scenes ``--layout`` can name."""
HALL_SHIFT = 0.6
"""Metres a hall table may move along its wall (x) and away from it (y), each way."""


@cache
def _template() -> dict[str, Any]:
    data = yaml.safe_load(TEMPLATE.read_text(encoding="utf-8"))
    assert isinstance(data, dict)
    return data


def scene(layout: str, rng: np.random.Generator, *, door: bool, trap: bool) -> dict[str, Any]:
    """The static parts of a problem file (robot, walls, regions, doors) for ``layout``."""
    if layout not in LAYOUTS:
        raise StalmError(f"unknown layout {layout!r} (available: {', '.join(LAYOUTS)})")
    template = copy.deepcopy(_template())
    regions: list[dict[str, Any]] = template["regions"]
    walls: list[dict[str, Any]] = template["walls"]
    if trap:
        walled = template["trap"]
        index = next(i for i, r in enumerate(regions) if r["name"] == walled["replaces"])
        regions[index] = walled["region"]
        walls = [*walls, *walled["walls"]]
    for region in regions:
        if region["room"] != "hall":
            continue
        dx, dy = (float(v) for v in rng.uniform(-HALL_SHIFT, HALL_SHIFT, 2))
        dy *= 0.5  # the two tables face each other across the hall: keep them apart
        region["center"] = [region["center"][0] + dx, region["center"][1] + dy]
        x, y, yaw = region["base_pose"]
        region["base_pose"] = [x + dx, y + dy, yaw]
    return {
        "robot": template["robot"],
        "walls": walls,
        "regions": regions,
        "doors": template["doors"] if door else [],
    }
