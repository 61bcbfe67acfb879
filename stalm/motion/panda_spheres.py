"""A conservative sphere model of the Panda's collision shapes, for batched collision tests.

Each link of the arm (and the hand and fingers) is covered by a few spheres in its URDF frame,
as VAMP and cuRobo model robots: a configuration's spheres come from forward kinematics alone,
and a sphere against a box or an upright cylinder is a handful of arithmetic. The model must
*contain* what PyBullet collides with, so that "no sphere touches" implies "PyBullet finds no
contact"; a sphere that touches is only a candidate, which the batched sweep confirms with
PyBullet (:mod:`stalm.motion.batch_sweep`).

The spheres are fitted to each link's real collision shape: rays are cast in PyBullet, from
all around the link (alone in a client of its own) towards its centre, so the hits are where
PyBullet's own shape is (the convex hull of the mesh, with its collision margin). Points
between the hits' centroid and each hit fill the solid (it is convex); they are grouped by
k-means into compact chunks, and each sphere is its chunk's bounding sphere about the chunk's
centroid, grown by :data:`MARGIN`, which covers the gaps between neighbouring hits. Chunks of
the solid rather than patches of the surface keep the spheres' centres inside the link, where
they bulge out least (measured on P3's predicates: fewer than half the candidate contacts
PyBullet then refutes). A test (``tests/motion/test_colliders.py``) checks the model against
PyBullet on random configurations next to random boxes and cans: no PyBullet contact without
a sphere contact.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import pybullet as p

from stalm.geometry.sphere_points import fibonacci_directions
from stalm.motion.panda import LINK_NAMES, panda_chain

MARGIN = 0.005
"""Metres each fitted sphere is grown by, for the gaps between ray hits (about 3 mm apart on
the largest link) and PyBullet's contact tolerance (1 mm). Measured: with 2 mm the model
already missed no contact in 6,000 random trials; 5 mm leaves a factor of 2.5."""
SPHERES_FILE = Path(__file__).with_name("panda_spheres.json")
"""The fitted model, shipped with the package (``python -m stalm.motion.panda_spheres``
fits it again: about 5 s)."""
RAYS = 6000
"""Rays cast at each link to find its surface."""
SPHERES_PER_METRE = 150.0
"""Chunks per metre of a link's longest extent (at least 2): 282 spheres for the arm."""
COLLIDING_LINKS = tuple(range(len(LINK_NAMES) - 1))
"""Frames of :data:`~stalm.motion.panda.LINK_NAMES` with a collision shape: links 0-7, the
hand and the fingers (not the grasp target, a frame only)."""


@dataclass(frozen=True)
class SphereModel:
    """Spheres in link frames: ``link[i]`` is the frame index of sphere i, ``centre[i]`` its
    centre in that frame and ``radius[i]`` its radius; a link's spheres are consecutive."""

    link: np.ndarray
    centre: np.ndarray
    radius: np.ndarray

    @property
    def groups(self) -> np.ndarray:
        """First and end index of each link's spheres (rows)."""
        starts = [0, *(i for i in range(1, len(self.link)) if self.link[i] != self.link[i - 1])]
        ends = [*starts[1:], len(self.link)]
        return np.array(list(zip(starts, ends, strict=True)), dtype=np.int64)


def _surface_points(client: int, mesh: Path, origin: np.ndarray) -> np.ndarray:
    """Points on the collision surface PyBullet makes of ``mesh`` (the convex hull of its
    vertices), alone in ``client``, in the link frame (``origin``: the URDF collision
    origin). Alone, because at any pose of the whole arm neighbouring links hide parts of
    each other from the rays."""
    shape = p.createCollisionShape(p.GEOM_MESH, fileName=str(mesh), physicsClientId=client)
    body = p.createMultiBody(0.0, shape, -1, [0, 0, 0], physicsClientId=client)
    low, high = p.getAABB(body, physicsClientId=client)
    centre = (np.array(low) + np.array(high)) / 2
    reach = float(np.linalg.norm(np.array(high) - np.array(low))) + 0.1
    starts = centre + reach * fibonacci_directions(RAYS)
    hits: list[tuple[float, float, float]] = []
    for begin in range(0, RAYS, 1000):
        chunk = starts[begin : begin + 1000]
        for result in p.rayTestBatch(
            chunk.tolist(), [centre.tolist()] * len(chunk), physicsClientId=client
        ):
            if result[0] == body:
                hits.append(result[3])
    p.removeBody(body, physicsClientId=client)
    points = np.array(hits)
    return points @ origin[:3, :3].T + origin[:3, 3]


def _clusters(points: np.ndarray, count: int) -> list[np.ndarray]:
    """``count`` clusters of ``points`` by k-means, started from slices along the principal
    axis (deterministic)."""
    mean = points.mean(axis=0)
    _, _, axes = np.linalg.svd(points - mean, full_matrices=False)
    order = np.argsort((points - mean) @ axes[0], kind="stable")
    centres = np.array([points[chunk].mean(axis=0) for chunk in np.array_split(order, count)])
    for _ in range(30):
        distances = np.linalg.norm(points[:, None, :] - centres[None, :, :], axis=2)
        label = distances.argmin(axis=1)
        moved = np.array(
            [
                points[label == k].mean(axis=0) if np.any(label == k) else centres[k]
                for k in range(count)
            ]
        )
        if np.allclose(moved, centres):
            break
        centres = moved
    distances = np.linalg.norm(points[:, None, :] - centres[None, :, :], axis=2)
    label = distances.argmin(axis=1)
    return [points[label == k] for k in range(count) if np.any(label == k)]


@cache
def panda_spheres() -> SphereModel:
    """The shipped sphere model (:data:`SPHERES_FILE`)."""
    data = json.loads(SPHERES_FILE.read_text())
    return SphereModel(
        np.array(data["link"], dtype=np.int64),
        np.array(data["centre"], dtype=float),
        np.array(data["radius"], dtype=float),
    )


def fit_panda_spheres() -> SphereModel:
    """Fit the model to PyBullet's collision shapes (see the module docstring)."""
    chain = panda_chain()
    client = p.connect(p.DIRECT)
    try:
        links, centres, radii = [], [], []
        for frame in COLLIDING_LINKS:
            name = LINK_NAMES[frame]
            points = _surface_points(
                client, chain.collision_meshes[name], chain.collision_origins[name]
            )
            extent = float(np.ptp(points, axis=0).max())
            middle = points.mean(axis=0)  # inside: a convex combination of the surface
            solid = np.concatenate(
                [middle + share * (points - middle) for share in np.linspace(0.0, 1.0, 11)[1:]]
            )
            for cluster in _clusters(solid, max(2, math.ceil(extent * SPHERES_PER_METRE))):
                centre = cluster.mean(axis=0)
                radius = float(np.linalg.norm(cluster - centre, axis=1).max()) + MARGIN
                links.append(frame)
                centres.append(centre)
                radii.append(radius)
    finally:
        p.disconnect(client)
    return SphereModel(np.array(links), np.array(centres), np.array(radii))


def _write(model: SphereModel) -> None:
    data = {
        "about": "Spheres covering the Franka Panda's collision shapes, by link frame "
        "(stalm.motion.panda.LINK_NAMES); written by python -m stalm.motion.panda_spheres",
        "margin": MARGIN,
        "link": model.link.tolist(),
        "centre": np.round(model.centre, 6).tolist(),
        "radius": np.round(model.radius + 1e-6, 6).tolist(),
    }
    SPHERES_FILE.write_text(json.dumps(data, indent=1) + "\n")


if __name__ == "__main__":
    _write(fit_panda_spheres())
    print(f"wrote {SPHERES_FILE}")
