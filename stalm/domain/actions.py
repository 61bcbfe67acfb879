"""Discrete actions of the G-TAMP domain: PICK(o), PLACE(o, dir, ref), OPEN(door).

A discrete action is the operator name with its discrete parameters (Table 1 of the paper);
its continuous parameters live in :mod:`stalm.domain.params`. Discrete actions are small
frozen values so they can key search-tree children and be compared across states.
"""

from __future__ import annotations

from dataclasses import dataclass

from stalm.geometry.directions import DIRECTIONS, RELATIVE_DIRECTIONS, Direction

__all__ = [
    "DIRECTIONS",
    "OPERATORS",
    "RELATIVE_DIRECTIONS",
    "Direction",
    "DiscreteAction",
    "Open",
    "Pick",
    "Place",
]

OPERATORS: tuple[str, ...] = ("pick", "place", "open")


@dataclass(frozen=True, order=True)
class Pick:
    """Grasp a movable object at its grasp point."""

    obj: str

    @property
    def operator(self) -> str:
        return "pick"

    def as_tuple(self) -> tuple[str, ...]:
        return ("pick", self.obj)

    def __str__(self) -> str:
        return f"pick({self.obj})"


@dataclass(frozen=True, order=True)
class Place:
    """Put the held object ``on`` a region, or left/right/front/behind of another object."""

    obj: str
    direction: Direction
    ref: str

    @property
    def operator(self) -> str:
        return "place"

    def as_tuple(self) -> tuple[str, ...]:
        return ("place", self.obj, self.direction, self.ref)

    def __str__(self) -> str:
        return f"place({self.obj}, {self.direction}, {self.ref})"


@dataclass(frozen=True, order=True)
class Open:
    """Pull a closed door open by its handle."""

    door: str

    @property
    def operator(self) -> str:
        return "open"

    def as_tuple(self) -> tuple[str, ...]:
        return ("open", self.door)

    def __str__(self) -> str:
        return f"open({self.door})"


DiscreteAction = Pick | Place | Open
