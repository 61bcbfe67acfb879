"""The scene as rows of primitives for the compiled collision tests, and the robot's spheres.

:class:`ScenePrimitives` turns a simulator's bodies into the rows
:mod:`stalm.motion.collision_primitives` reads: the static scene (walls, counters, tables) once,
the doors and objects as the simulator has them at each question, and the held object in the
gripper's frame (a can as its box and its spheres, a grill or a box as its boxes, a mesh as a
box around each of its convex pieces). Every body has a column, the index the candidate test
marks.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from functools import cache

import numpy as np
import pybullet as p

from stalm.geometry.transforms import quat_yaw
from stalm.motion.arm_model import arm_of
from stalm.motion.sphere_fit import CONTACT_MARGIN
from stalm.world.mesh_pieces import object_pieces
from stalm.world.object_spec import GRILL_HANDLE_HALF_HEIGHT, GRILL_HANDLE_REACH, ObjectSpec
from stalm.world.scene import Sim
from stalm.world.spec import DoorSpec
from stalm.world.state import Grasp

BOXED_SHAPES = ("grill", "box", "mesh")
"""Shapes the batched engine tests as oriented boxes, and a held one as boxes: a grill's and a
box's rows are their collision shapes exactly; a mesh's cover its convex pieces."""
MESH_BOX_PADDING = 2 * CONTACT_MARGIN
"""How far a mesh piece's box reaches past the piece's vertices (m): PyBullet reports contacts
of convex hulls up to their collision margin apart, so the cover must hold the hull grown by it
(twice it, for slack)."""

MOST_PIECE_BOXES = 8
"""The most boxes a mesh is covered by, one per convex piece; a mesh of more pieces (V-HACD
gives a LEGO brick 42, a procedural toy may have 50) is covered by one box around them all:
every box is tested at every step of every motion, and a candidate the looser cover adds is
only confirmed by PyBullet, so the literals are the same (measured on a scene of 64 objects
with 30 meshes: the predicates took 74 s with a box per piece, 44 s with this)."""


def box_row(
    centre: Sequence[float], half: Sequence[float], rotation: np.ndarray, column: int
) -> np.ndarray:
    row = np.empty(16)
    row[:3] = centre
    row[3:6] = half
    row[6:15] = rotation.reshape(9)
    row[15] = column
    return row


def yaw_rotation(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def object_boxes(obj: ObjectSpec) -> list[tuple[tuple[float, float, float], tuple[float, ...]]]:
    """An object's collision boxes in its own frame (origin at its bottom centre): (centre,
    half extents) each; a box's is itself, a cylinder's is its bounding box, a mesh's are the
    bounding boxes (in its frame, grown by :data:`MESH_BOX_PADDING`) of its convex pieces."""
    if obj.shape == "grill":
        assert obj.size is not None
        sx, sy, sz = obj.size
        handle = (GRILL_HANDLE_HALF_HEIGHT, GRILL_HANDLE_REACH / 2, GRILL_HANDLE_HALF_HEIGHT)
        side = sy / 2 + GRILL_HANDLE_REACH / 2
        return [
            ((0.0, 0.0, sz / 2), (sx / 2, sy / 2, sz / 2)),
            ((0.0, side, obj.handle_z), handle),
            ((0.0, -side, obj.handle_z), handle),
        ]
    if obj.shape == "box":
        half = obj.half_extents
        return [((0.0, 0.0, half[2]), half)]
    if obj.shape == "mesh":
        return list(_mesh_boxes(obj))
    assert obj.radius is not None and obj.height is not None
    return [((0.0, 0.0, obj.height / 2), (obj.radius, obj.radius, obj.height / 2))]


def door_boxes(door: DoorSpec) -> list[tuple[tuple[float, float, float], tuple[float, ...]]]:
    """A door's collision boxes in its frame (origin at its hinge): its leaf and its handle."""
    return [
        (
            (door.width / 2, 0.0, door.height / 2),
            (door.width / 2, door.thickness / 2, door.height / 2),
        ),
        ((door.handle_distance, 0.0, door.handle_height), (0.02, door.thickness / 2 + 0.05, 0.06)),
    ]


@cache
def _mesh_boxes(
    obj: ObjectSpec,
) -> tuple[tuple[tuple[float, float, float], tuple[float, ...]], ...]:
    """A mesh object's piece boxes, computed once (the scene asks for them at every test); a
    mesh of more than :data:`MOST_PIECE_BOXES` pieces is one box around them all."""
    pieces = object_pieces(obj).vertices
    if len(pieces) > MOST_PIECE_BOXES:
        return (_piece_box(np.vstack(pieces)),)
    return tuple(_piece_box(piece) for piece in pieces)


def _piece_box(
    vertices: np.ndarray,
) -> tuple[tuple[float, float, float], tuple[float, ...]]:
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    centre, half = (low + high) / 2, (high - low) / 2 + MESH_BOX_PADDING
    return (
        (float(centre[0]), float(centre[1]), float(centre[2])),
        tuple(float(h) for h in half),
    )


def cylinder_spheres(obj: ObjectSpec) -> tuple[np.ndarray, float]:
    """Spheres covering a cylinder-shaped object (a can, a bottle, a plate) in its frame
    (origin at its bottom centre): centres along the axis and their common radius (a point of
    the side at most half a spacing from a centre is within it; so are the caps' rims)."""
    assert obj.radius is not None and obj.height is not None
    count = max(2, math.ceil(obj.height / obj.radius) + 1)
    spacing = obj.height / (count - 1)
    centres = np.zeros((count, 3))
    centres[:, 2] = np.linspace(0.0, obj.height, count)
    return centres, math.hypot(obj.radius, spacing / 2) + 0.001


class ScenePrimitives:
    """One simulator's bodies as primitive rows (see the module docstring)."""

    def __init__(self, sim: Sim) -> None:
        self.sim = sim
        bodies = sim.bodies
        self.columns: list[int] = [
            *bodies.walls.values(),
            *bodies.regions.values(),
            *bodies.doors.values(),
            *bodies.objects.values(),
        ]
        self.column_of = {body: index for index, body in enumerate(self.columns)}
        spec = sim.problem
        static = []
        for wall in spec.walls:
            column = self.column_of[bodies.walls[wall.name]]
            static.append(
                box_row(wall.center, [s / 2 for s in wall.size], yaw_rotation(wall.yaw), column)
            )
        for region in spec.regions:
            thickness = region.thickness if region.thickness is not None else region.top
            centre = (region.center[0], region.center[1], region.top - thickness / 2)
            half = (region.size[0] / 2, region.size[1] / 2, thickness / 2)
            column = self.column_of[bodies.regions[region.name]]
            static.append(box_row(centre, half, yaw_rotation(region.yaw), column))
        self._static = np.array(static).reshape(-1, 16)
        self._objects = {obj.name: obj for obj in spec.objects}
        self._parts: dict[int, list[tuple[tuple[float, float, float], tuple[float, ...]]]] = {
            bodies.doors[door.name]: door_boxes(door) for door in spec.doors
        }
        self._parts.update(
            (bodies.objects[obj.name], object_boxes(obj))
            for obj in spec.objects
            if obj.shape in BOXED_SHAPES
        )
        self._rows_at: dict[int, tuple[object, np.ndarray]] = {}
        arm = arm_of(sim)
        self.spheres = arm.spheres
        self.groups = self.spheres.groups
        self.grasp_frame = arm.grasp_frame
        mount = sim.robot.platform
        self.base_box = np.array(
            [
                box_row(
                    (0.0, 0.0, mount.base_height / 2),
                    (mount.base_radius, mount.base_radius, mount.base_height / 2),
                    np.eye(3),
                    0,
                )
            ]
        )

    def world(
        self, ignore: Iterable[int], only: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Boxes and cylinders of every body but the robot's, as the simulator has them now;
        the bodies in ``ignore`` (and a held object) get column -1 (never candidates). With
        ``only`` (a door's or a movable object's body), that body's primitives and nothing
        else: a motion is tested against one body that moved."""
        sim = self.sim
        skipped = set(ignore)
        if sim.held is not None:
            skipped.add(sim.bodies.objects[sim.held.obj])
        boxes = [self._static] if self._static.size and only is None else []
        cylinders = []
        client = sim.client
        for door in sim.problem.doors:
            body = sim.bodies.doors[door.name]
            if only is None or body == only:
                boxes.append(self._rows(body, -1 if body in skipped else self.column_of[body]))
        for name, obj in self._objects.items():
            body = sim.bodies.objects[name]
            if only is not None and body != only:
                continue
            column = -1 if body in skipped else self.column_of[body]
            if obj.shape in BOXED_SHAPES:
                boxes.append(self._rows(body, column))
            else:
                assert obj.radius is not None and obj.height is not None
                position, _ = p.getBasePositionAndOrientation(body, physicsClientId=client)
                x, y, z = position
                cylinders.append((x, y, z, z + obj.height, obj.radius, column))
        box_rows = np.concatenate(boxes) if boxes else np.zeros((0, 16))
        return box_rows, np.array(cylinders, dtype=float).reshape(-1, 6)

    def _rows(self, body: int, column: int) -> np.ndarray:
        """The box rows of a door or a boxed object where the simulator has it now, marked
        ``column``: made again only when the body has moved (a mesh of many pieces has a row
        per piece, and a scene of them is asked for at every motion tested)."""
        pose = p.getBasePositionAndOrientation(body, physicsClientId=self.sim.client)
        known = self._rows_at.get(body)
        if known is None or known[0] != pose:
            position, orientation = pose
            rotation = yaw_rotation(quat_yaw(orientation))
            parts = [
                box_row(np.asarray(position) + rotation @ np.asarray(centre), half, rotation, 0)
                for centre, half in self._parts[body]
            ]
            known = (pose, np.array(parts).reshape(-1, 16))
            self._rows_at[body] = known
        rows = known[1].copy()
        rows[:, 15] = column
        return rows

    def with_held(self) -> tuple[np.ndarray, ...]:
        """The spheres (links, centres, radii, groups) of the robot with the held object's
        (a can's, in the grasp target's frame), its boxes in that frame, and each box's sphere
        group (-1: none, a grill's)."""
        spheres, groups = self.spheres, self.groups
        held: Grasp | None = self.sim.held
        if held is None:
            empty = np.zeros(0, dtype=np.int64)
            return spheres.link, spheres.centre, spheres.radius, groups, np.zeros((0, 16)), empty
        obj = self._objects[held.obj]
        grasp_rotation = np.array(p.getMatrixFromQuaternion(held.orientation)).reshape(3, 3)
        rows = []
        for centre, half in object_boxes(obj):
            local = np.asarray(held.position) + grasp_rotation @ np.asarray(centre)
            rows.append(box_row(local, half, grasp_rotation, 0))
        if obj.shape in BOXED_SHAPES:
            box_groups = np.full(len(rows), -1, dtype=np.int64)
            return spheres.link, spheres.centre, spheres.radius, groups, np.array(rows), box_groups
        centres, radius = cylinder_spheres(obj)
        local_centres = np.asarray(held.position) + centres @ grasp_rotation.T
        start = len(spheres.link)
        return (
            np.concatenate([spheres.link, np.full(len(local_centres), self.grasp_frame)]),
            np.concatenate([spheres.centre, local_centres]),
            np.concatenate([spheres.radius, np.full(len(local_centres), radius)]),
            np.concatenate([groups, [[start, start + len(local_centres)]]]).astype(np.int64),
            np.array(rows),
            np.array([len(groups)], dtype=np.int64),
        )
