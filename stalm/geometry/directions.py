"""The five placement directions of AtPosition and PLACE (pure names, no geometry needed)."""

from __future__ import annotations

from typing import Literal

Direction = Literal["on", "left_of", "right_of", "front_of", "behind_of"]
DIRECTIONS: tuple[Direction, ...] = ("on", "left_of", "right_of", "front_of", "behind_of")
RELATIVE_DIRECTIONS: tuple[Direction, ...] = ("left_of", "right_of", "front_of", "behind_of")
