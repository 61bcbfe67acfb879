"""Where a robot's fitted spheres come from: shipped beside its file, cached, or fitted now.

A fit takes seconds (:mod:`stalm.motion.sphere_fit`), so it is done once per robot shape. A
sphere set is valid for the exact collision shapes it was fitted to, so it records the URDF's
content hash (the URDF's text and every collision mesh, :attr:`Robot.urdf_sha256`) and the
fit's ``delta``; a set whose hash differs is never used. Looked up in order:

1. ``<robot file>.spheres.json`` beside the robot file: the built-in robots ship theirs
   (``python -m stalm.motion.sphere_fit_store`` writes them again), so nothing is fitted at
   run time for them; a user may ship one beside their own robot file too; else a built-in
   robot's set fitted to the same URDF (a robot file that mounts a shipped arm otherwise);
2. the cache (``<stalm cache>/spheres/<hash>-<delta>.json``);
3. a new fit, with a Generator seeded by :data:`FIT_SEED`, written to the cache.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stalm.cache_dir import stalm_cache_dir
from stalm.errors import StalmError, StalmWarning
from stalm.files import read_json_file, write_replacing
from stalm.motion.sphere_fit import (
    CHECK_SAMPLES,
    DELTA,
    LinkSpheres,
    SphereCheck,
    check_spheres,
    fit_link_spheres,
)
from stalm.world.link_shapes import body_convex_parts
from stalm.world.robot_description import ROBOTS_DIR, Robot
from stalm.world.robot_loader import builtin_robots, load_robot
from stalm.world.robot_urdf import urdf_body

FIT_SEED = 0
"""Seed of the Generator a fit draws from: the same robot always gets the same spheres."""
FORMAT = 1
"""Version of the JSON layout and of the fit; a file of another is not used."""


@dataclass(frozen=True)
class RobotSpheres:
    """Every colliding link's spheres, and what they were fitted to."""

    robot: str
    urdf_sha256: str
    delta: float
    links: tuple[LinkSpheres, ...]

    @property
    def total(self) -> int:
        return sum(len(link.radii) for link in self.links)

    def by_link(self) -> dict[str, LinkSpheres]:
        return {link.link: link for link in self.links}


def fit_robot_spheres(robot: Robot, rng: np.random.Generator, delta: float = DELTA) -> RobotSpheres:
    """Fit spheres to every link of ``robot`` that has collision geometry."""
    with urdf_body(robot.urdf_path) as loaded:
        parts = body_convex_parts(loaded)
    links = tuple(fit_link_spheres(name, points, rng, delta) for name, points in parts.items())
    return RobotSpheres(robot.name, robot.urdf_sha256, delta, links)


def check_robot_spheres(
    robot: Robot, spheres: RobotSpheres, rng: np.random.Generator, samples: int = CHECK_SAMPLES
) -> SphereCheck:
    """:func:`~stalm.motion.sphere_fit.check_spheres` against ``robot``'s collision shapes."""
    with urdf_body(robot.urdf_path) as loaded:
        parts = body_convex_parts(loaded)
    return check_spheres(parts, spheres.by_link(), rng, samples)


def spheres_to_json(spheres: RobotSpheres) -> str:
    links = {
        link.link: {
            "centres": np.round(link.centres, 6).tolist(),
            "radii": np.round(link.radii, 6).tolist(),
        }
        for link in spheres.links
    }
    return json.dumps(
        {
            "about": f"spheres covering {spheres.robot}'s collision shapes, by link, in each "
            "link's URDF frame (m); written by stalm.motion.sphere_fit_store",
            "format": FORMAT,
            "robot": spheres.robot,
            "urdf_sha256": spheres.urdf_sha256,
            "delta": spheres.delta,
            "links": links,
        },
        indent=1,
    )


def spheres_from_json(path: Path) -> RobotSpheres:
    """A sphere set written by :func:`spheres_to_json`; a StalmError naming the file if not."""
    data = read_json_file(path, "sphere file", finite=True)
    try:
        links = tuple(
            LinkSpheres(
                name,
                np.asarray(entry["centres"], dtype=float).reshape(-1, 3),
                np.asarray(entry["radii"], dtype=float).reshape(-1),
            )
            for name, entry in data["links"].items()
        )
        if data["format"] != FORMAT or any(len(s.centres) != len(s.radii) for s in links):
            raise ValueError("another format")
        return RobotSpheres(
            str(data["robot"]), str(data["urdf_sha256"]), float(data["delta"]), links
        )
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise StalmError(f"{path}: not a sphere file of format {FORMAT} ({error})") from None


def beside_file(robot: Robot) -> Path:
    """Where a robot file's shipped spheres are: ``<name>.spheres.json`` beside it."""
    source = Path(robot.source)
    return source.with_name(f"{source.stem}.spheres.json")


def cache_file(robot: Robot, delta: float) -> Path:
    return stalm_cache_dir() / "spheres" / f"{robot.urdf_sha256}-{delta:g}.json"


def _usable(path: Path, robot: Robot, delta: float) -> RobotSpheres | None:
    if not path.is_file():
        return None
    try:
        spheres = spheres_from_json(path)
    except StalmError:
        return None
    if spheres.urdf_sha256 != robot.urdf_sha256 or spheres.delta != delta:
        return None
    return spheres


def robot_spheres(robot: Robot, delta: float = DELTA) -> tuple[RobotSpheres, str]:
    """``robot``'s spheres and where they came from (``shipped``, ``cache`` or ``fitted``)."""
    shipped = _usable(beside_file(robot), robot, delta)
    for name in builtin_robots():  # another file of a shipped URDF (a fixed Panda, say)
        if shipped is None:
            shipped = _usable(ROBOTS_DIR / f"{name}.spheres.json", robot, delta)
    if shipped is not None:
        return shipped, "shipped"
    cached = _usable(cache_file(robot, delta), robot, delta)
    if cached is not None:
        return cached, "cache"
    spheres = fit_robot_spheres(robot, np.random.default_rng(FIT_SEED), delta)
    try:
        write_replacing(cache_file(robot, delta), spheres_to_json(spheres))
    except OSError as error:
        warnings.warn(
            f"cannot cache {robot.name}'s spheres ({error}); they are fitted again next time",
            StalmWarning,
            stacklevel=2,
        )
    return spheres, "fitted"


def write_spheres_beside(robot: Robot) -> Path:
    """Fit ``robot``'s spheres and write them beside its robot file, where
    :func:`robot_spheres` looks first (how the built-in robots' sets are made)."""
    spheres = fit_robot_spheres(robot, np.random.default_rng(FIT_SEED))
    path = beside_file(robot)
    write_replacing(path, spheres_to_json(spheres) + "\n")
    return path


if __name__ == "__main__":  # pragma: no cover - rewrites the package's own files
    for name in builtin_robots():
        print(f"{name}: wrote {write_spheres_beside(load_robot(name))}")
