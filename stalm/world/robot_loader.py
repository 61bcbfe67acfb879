"""Loading a robot by name or path: a built-in robot file, or any other, checked against its URDF.

Kept apart from the file's model (:mod:`stalm.world.robot_description`), which says what a
valid robot file is, and from the URDF's side (:mod:`stalm.world.robot_urdf`).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

from stalm.errors import StalmError
from stalm.world.robot_description import ROBOTS_DIR, Robot, read_robot_spec, resolve_urdf
from stalm.world.robot_urdf import check_against_urdf


def builtin_robots() -> tuple[str, ...]:
    """Names of the robots shipped with stalm, sorted."""
    return tuple(sorted(path.stem for path in ROBOTS_DIR.glob("*.yaml")))


def robot_file(name_or_path: str) -> Path:
    """The file of a built-in robot's name, else ``name_or_path`` as a path; a StalmError
    listing the built-in robots for a bare name that is neither (a typo, not a missing file)."""
    names = builtin_robots()
    if name_or_path in names:
        return ROBOTS_DIR / f"{name_or_path}.yaml"
    path = Path(name_or_path)
    if not path.exists() and path.suffix == "" and len(path.parts) == 1:
        raise StalmError(
            f"no robot {name_or_path!r}: give a robot file or one of {', '.join(names)}"
        )
    return path


def load_robot(name_or_path: str) -> Robot:
    """A built-in robot by name or a robot file by path, validated against its URDF."""
    path = robot_file(name_or_path)
    spec = read_robot_spec(path)
    return check_against_urdf(spec, str(path), resolve_urdf(spec.urdf, path.parent))


@cache
def robot_named(name_or_path: str) -> Robot:
    """:func:`load_robot`, once per process for each name or path: every scene of a run
    builds its robot from it, and loading reads the URDF in PyBullet."""
    return load_robot(name_or_path)
