"""The sizes of pictures and animations, and their check: plain numbers, importable without
PyBullet (the command line checks ``--size`` and ``--gif-size`` before anything is built)."""

from __future__ import annotations

from stalm.errors import StalmError

MIN_SIZE = 16
MAX_SIZE = 4096
"""Pixels per view: PyBullet's renderer divided by zero below 1, aborted on a negative size
and crashed the process at 30000 (a 60000 x 30000 canvas)."""

GIF_SIZE = 240
"""Pixels of each of an animation's two square views (``--gif-size``)."""


def check_size(size: int, name: str = "size") -> int:
    """``size`` if it is within [:data:`MIN_SIZE`, :data:`MAX_SIZE`], else a StalmError
    naming ``name`` (``--size`` on the command line)."""
    if not MIN_SIZE <= size <= MAX_SIZE:
        raise StalmError(f"{name} must be between {MIN_SIZE} and {MAX_SIZE} pixels, got {size}")
    return size
