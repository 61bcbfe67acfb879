"""The convex shapes each link of a URDF collides with, as PyBullet builds them.

A link on a moving body collides as convex shapes: each collision mesh becomes the convex hull
of its vertices (a mesh of several objects, a hull per object) and primitives stay primitives.
Here each collision element of a link becomes one convex point set in the link's URDF frame
whose hull contains what PyBullet collides with:

- a mesh: the vertices ``getMeshData`` returns (the hulls' vertices, in the link's *inertial*
  frame, moved here into the URDF frame). A mesh of several hulls gives one point set for them
  all: its hull contains theirs, a looser but still containing shape;
- a box: its corners;
- a sphere: a polytope circumscribing it (its faces touch the sphere or lie outside it), so
  that covering the polytope covers the sphere. (PyBullet loads a URDF's cylinder and capsule
  as meshes, hulls of points on their surfaces, which ``getMeshData`` returns.)
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from stalm.errors import StalmError
from stalm.geometry.sphere_points import fibonacci_directions
from stalm.geometry.transforms import pose_matrix
from stalm.world.robot_urdf import UrdfBody

SPHERE_POINTS = 162
"""Points of the polytope circumscribing a sphere."""


def _unit_ball_polytope() -> np.ndarray:
    """Points whose hull contains the unit ball: Fibonacci points scaled so that the hull's
    nearest face to the centre is 1 away."""
    from scipy.spatial import ConvexHull

    points = fibonacci_directions(SPHERE_POINTS)
    inradius = float(-ConvexHull(points).equations[:, 3].max())
    return points / inradius


def _primitive_points(kind: int, dimensions: tuple[float, ...]) -> np.ndarray:
    if kind == p.GEOM_BOX:
        half = np.asarray(dimensions[:3]) / 2.0
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        return signs * half
    if kind == p.GEOM_SPHERE:
        return _unit_ball_polytope() * dimensions[0]
    raise StalmError(f"collision geometry of PyBullet type {kind} is not supported on a robot")


def transformed(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` (n x 3) moved by the 4x4 transform ``matrix``."""
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def link_convex_parts(loaded: UrdfBody, link: int) -> list[np.ndarray]:
    """The convex point sets (n x 3, URDF link frame) of one link's collision elements; empty
    for a link without collision geometry (a bare frame such as a grasp target)."""
    c = loaded.client
    inertial = loaded.inertial_offset(link)
    shapes = p.getCollisionShapeData(loaded.body, link, physicsClientId=c)
    parts: list[np.ndarray] = []
    for number, shape in enumerate(shapes):
        kind = int(shape[2])
        if kind == p.GEOM_MESH:
            if len(shapes) == 1:  # every hull of a multi-object mesh, not only the first
                mesh = p.getMeshData(loaded.body, link, physicsClientId=c)
            else:
                mesh = p.getMeshData(
                    loaded.body, link, collisionShapeIndex=number, physicsClientId=c
                )
            points = np.asarray(mesh[1], dtype=float).reshape(-1, 3)
        else:
            local = pose_matrix((shape[5], shape[6]))
            points = transformed(local, _primitive_points(kind, tuple(shape[3])))
        if len(points):
            parts.append(transformed(inertial, points))
    return parts


def body_convex_parts(loaded: UrdfBody) -> dict[str, list[np.ndarray]]:
    """:func:`link_convex_parts` of every link that has collision geometry, by link name."""
    parts = {name: link_convex_parts(loaded, index) for name, index in loaded.links.items()}
    return {name: shapes for name, shapes in parts.items() if shapes}
