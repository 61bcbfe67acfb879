"""The values a problem file's fields may take: names, coordinates, sizes, colours.

Kept apart from the spec models (:mod:`stalm.world.spec`) so the bounds are stated once: every
coordinate, size and angle lies within :data:`MAX_EXTENT`, a colour's channels in [0, 1], a
name is an identifier. Pydantic checks them field by field, so an error names the field
(``walls[0].size.0: Input should be less than or equal to 1000``).
"""

from __future__ import annotations

import re
from typing import Annotated

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")


def _check_name(name: str) -> str:
    """Names go into PDDL, prompts, replies and terminals: letters, digits and underscores."""
    if not _NAME.fullmatch(name):
        raise ValueError(
            f"{name!r:.80} is not a name: use up to 64 letters, digits and '_', starting with a "
            "letter (names are written into PDDL and prompts)"
        )
    return name


MAX_EXTENT = 1000.0
"""Every coordinate, size and angle of a problem lies within +-1000 (m, rad): what the world can
hold. Far beyond it PyBullet silently drops a body from collision checks and rendering (a wall
1e308 m long vanished) and the roadmap's arithmetic overflows (a 1e308 m floor)."""
MAX_FLOOR_SIDE = 100.0
"""A floor's side (m): the scene check floods the floor on a 10 cm grid, a million cells at
this size (the six problems' floors are 10 m)."""

Name = Annotated[str, AfterValidator(_check_name)]
Coordinate = Annotated[float, Field(ge=-MAX_EXTENT, le=MAX_EXTENT)]
"""A position or an angle (see :data:`MAX_EXTENT`)."""
Positive = Annotated[float, Field(gt=0, le=MAX_EXTENT)]
"""A size: above 0 and at most :data:`MAX_EXTENT`."""
Unit = Annotated[float, Field(ge=0, le=1)]
Vec2 = tuple[Coordinate, Coordinate]
Vec3 = tuple[Coordinate, Coordinate, Coordinate]
RGBA = tuple[Unit, Unit, Unit, Unit]

__all__ = [
    "MAX_EXTENT",
    "MAX_FLOOR_SIDE",
    "RGBA",
    "Coordinate",
    "Name",
    "Positive",
    "Unit",
    "Vec2",
    "Vec3",
]


class SpecModel(BaseModel):
    """The base of every spec model: unknown fields refused, frozen, and no NaN or infinity
    (NaN passes every comparison check, NaN > x being false, and crashes much later)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
