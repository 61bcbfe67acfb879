"""Compiled candidate tests: which bodies a robot motion may touch, for many steps at once.

A step is one arm configuration at a standing pose, or one base pose of a route with the arm
as it is. The robot is the sphere model of the arm (:mod:`stalm.motion.arm_model`) on its frames at
each step, computed before (by the arm's own compiled forward kinematics), plus
boxes for what moves with it: the base column (its cylinder's bounding box) on a route, the
held object's boxes in the gripper frame. The world is boxes (walls, counters, tables, door
panels and handles, the grill's parts) and upright cylinders (cans, bottles, plates). Each
test is conservative: a sphere that touches a box or a cylinder, or two boxes that the
separating-axis test cannot separate, mark the body as a *candidate* at that step; a body no
test marks cannot be in contact (the sphere model contains the arm's collision shapes, and a
bounding box its cylinder). The caller confirms candidates with PyBullet.

Every primitive carries its axis-aligned bounding box, and a step's robot has one too, so most
pairs are dismissed by six comparisons before any sphere is looked at; so is every link (its
bounding sphere's box) before its bounding sphere is tested exactly, and within a link that
comes near, each part of a few neighbouring spheres has a bounding sphere of its own. These
prunings change what is computed, not what is found: a primitive the box of a sphere misses,
the sphere misses too.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from stalm.motion.collision_primitives import (
    apart,
    box_aabb,
    boxes_may_touch,
    cylinder_box,
    place_box,
    sphere_touches_box,
    sphere_touches_cylinder,
)

PART_SIZE = 6
"""Spheres in a part: a group's (a link's) consecutive spheres are tested in parts of this
many, each behind its own bounding sphere. Consecutive spheres are neighbours: the fitted
model's come in slices along each link's principal axis (:mod:`stalm.motion.panda_spheres`),
a held can's along its axis. Measured on P3's and Clutter35's full computations: 6 spheres a
part take a fifth less time than one part a link; reordering them (a k-d split) 3% less,
which was not kept."""


@numba.njit(cache=True)
def _touches_primitive(
    centre_x: float,
    centre_y: float,
    centre_z: float,
    radius: float,
    kind: int,
    b: int,
    boxes: np.ndarray,
    cylinders: np.ndarray,
    point: np.ndarray,
) -> bool:
    point[0], point[1], point[2] = centre_x, centre_y, centre_z
    if kind == 0:
        return sphere_touches_box(point, radius, boxes[b])
    return sphere_touches_cylinder(point, radius, cylinders[b])


@numba.njit(cache=True)
def _group_touches(
    g: int,
    kind: int,
    b: int,
    state: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    model: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    boxes: np.ndarray,
    cylinders: np.ndarray,
) -> bool:
    """Does a sphere of group ``g`` touch box ``b`` (``kind`` 0) or cylinder ``b`` (1)? The
    group's bounding sphere is tried first, then the bounding sphere of each of its parts (a
    few neighbouring spheres), then that part's spheres; each is placed in the world only when
    first needed in this step (most groups are far from every body most of the time, and a
    link near a surface is near it with a few of its parts)."""
    frames, group_world, placed, centres, point, part_world = state
    sphere_link, sphere_centre, sphere_radius, parts, group_parts, part_bounds = model
    if not _touches_primitive(
        group_world[g, 0],
        group_world[g, 1],
        group_world[g, 2],
        group_world[g, 3],
        kind,
        b,
        boxes,
        cylinders,
        point,
    ):
        return False
    for q in range(group_parts[g, 0], group_parts[g, 1]):
        link = sphere_link[parts[q, 0]]
        if placed[q] == 0:  # the part's bounding sphere, in the world
            for r in range(3):
                part_world[q, r] = (
                    frames[link, r, 0] * part_bounds[q, 0]
                    + frames[link, r, 1] * part_bounds[q, 1]
                    + frames[link, r, 2] * part_bounds[q, 2]
                    + frames[link, r, 3]
                )
            part_world[q, 3] = part_bounds[q, 3]
            placed[q] = 1
        if not _touches_primitive(
            part_world[q, 0],
            part_world[q, 1],
            part_world[q, 2],
            part_world[q, 3],
            kind,
            b,
            boxes,
            cylinders,
            point,
        ):
            continue
        if placed[q] == 1:  # its spheres, in the world
            for i in range(parts[q, 0], parts[q, 1]):
                cx, cy, cz = sphere_centre[i, 0], sphere_centre[i, 1], sphere_centre[i, 2]
                for r in range(3):
                    centres[i, r] = (
                        frames[link, r, 0] * cx
                        + frames[link, r, 1] * cy
                        + frames[link, r, 2] * cz
                        + frames[link, r, 3]
                    )
            placed[q] = 2
        for i in range(parts[q, 0], parts[q, 1]):
            if _touches_primitive(
                centres[i, 0],
                centres[i, 1],
                centres[i, 2],
                sphere_radius[i],
                kind,
                b,
                boxes,
                cylinders,
                point,
            ):
                return True
    return False


@numba.njit(cache=True)
def _bounding_sphere(
    first: int, end: int, sphere_centre: np.ndarray, sphere_radius: np.ndarray, out: np.ndarray
) -> None:
    """A sphere containing spheres ``first`` to ``end`` (their box's centre, and the farthest
    reach from it) into ``out`` (x, y, z, radius), in their link's frame."""
    for i in range(3):
        lo, hi = 1e18, -1e18
        for k in range(first, end):
            lo = min(lo, sphere_centre[k, i] - sphere_radius[k])
            hi = max(hi, sphere_centre[k, i] + sphere_radius[k])
        out[i] = (lo + hi) / 2
    out[3] = 0.0
    for k in range(first, end):
        extent = (
            math.sqrt(
                (sphere_centre[k, 0] - out[0]) ** 2
                + (sphere_centre[k, 1] - out[1]) ** 2
                + (sphere_centre[k, 2] - out[2]) ** 2
            )
            + sphere_radius[k]
        )
        out[3] = max(out[3], extent)


@numba.njit(cache=True)
def _sphere_apart(sphere: np.ndarray, low: np.ndarray, high: np.ndarray) -> bool:
    """Is the sphere (x, y, z, radius) clear of the box from ``low`` to ``high``? Six
    comparisons, cheaper than any exact test, and most group-primitive pairs are clear."""
    for i in range(3):  # noqa: SIM110 - numba compiles loops, not generators
        if sphere[i] + sphere[3] < low[i] or sphere[i] - sphere[3] > high[i]:
            return True
    return False


@numba.njit(cache=True)
def _mark_step(
    step: int,
    state: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    model: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    arm_groups: int,
    moving_boxes: np.ndarray,
    box_group: np.ndarray,
    boxes: np.ndarray,
    box_low: np.ndarray,
    box_high: np.ndarray,
    cylinders: np.ndarray,
    out: np.ndarray,
    work: tuple[np.ndarray, ...],
) -> None:
    """Mark in ``out[step]`` every body a sphere or a moving box of this step may touch.

    Groups of spheres (one per link, then the held object's) each have a bounding sphere,
    placed in the world (``state``'s ``group_world``) before this is called: the first
    ``arm_groups`` are the arm's links, each tested alone; a moving box ``m`` with
    ``box_group[m] >= 0`` marks a body only if that group's spheres touch it too (a held can
    is inside both its box and its spheres: each alone is loose, at the box's corners or the
    spheres' caps). A body is compared with anything only if it meets the bounding box of the
    whole robot."""
    group_world = state[1]
    group_parts = model[4]
    low, high, moving_low, moving_high, cylinder_low, cylinder_high, as_box, axis = work
    for i in range(3):
        low[i] = 1e18
        high[i] = -1e18
    for g in range(group_parts.shape[0]):
        for i in range(3):
            low[i] = min(low[i], group_world[g, i] - group_world[g, 3])
            high[i] = max(high[i], group_world[g, i] + group_world[g, 3])
    for m in range(moving_boxes.shape[0]):
        box_aabb(moving_boxes[m], moving_low[m], moving_high[m])
        for i in range(3):
            low[i] = min(low[i], moving_low[m, i])
            high[i] = max(high[i], moving_high[m, i])
    for kind in range(2):
        total = boxes.shape[0] if kind == 0 else cylinders.shape[0]
        for b in range(total):
            if kind == 0:
                body = int(boxes[b, 15])
                primitive_low, primitive_high = box_low[b], box_high[b]
            else:
                cyl = cylinders[b]
                body = int(cyl[5])
                cylinder_low[0], cylinder_low[1], cylinder_low[2] = (
                    cyl[0] - cyl[4],
                    cyl[1] - cyl[4],
                    cyl[2],
                )
                cylinder_high[0], cylinder_high[1], cylinder_high[2] = (
                    cyl[0] + cyl[4],
                    cyl[1] + cyl[4],
                    cyl[3],
                )
                primitive_low, primitive_high = cylinder_low, cylinder_high
            if body < 0 or out[step, body]:
                continue
            if apart(primitive_low, primitive_high, low, high):
                continue
            hit = False
            for g in range(arm_groups):
                if hit:
                    break
                if _sphere_apart(group_world[g], primitive_low, primitive_high):
                    continue
                hit = _group_touches(g, kind, b, state, model, boxes, cylinders)
            for m in range(moving_boxes.shape[0]):
                if hit:
                    break
                if apart(primitive_low, primitive_high, moving_low[m], moving_high[m]):
                    continue
                if kind == 0:
                    hit = boxes_may_touch(moving_boxes[m], boxes[b], axis)
                else:
                    cylinder_box(cylinders[b], as_box)
                    hit = boxes_may_touch(moving_boxes[m], as_box, axis)
                if hit and box_group[m] >= 0:
                    hit = _group_touches(box_group[m], kind, b, state, model, boxes, cylinders)
            if hit:
                out[step, body] = True


@numba.njit(cache=True)
def candidate_steps(
    stands: np.ndarray,
    step_frames: np.ndarray,
    grasp: int,
    sphere_link: np.ndarray,
    sphere_centre: np.ndarray,
    sphere_radius: np.ndarray,
    sphere_groups: np.ndarray,
    arm_groups: int,
    held_boxes: np.ndarray,
    held_box_group: np.ndarray,
    base_boxes: np.ndarray,
    boxes: np.ndarray,
    cylinders: np.ndarray,
    bodies: int,
) -> np.ndarray:
    """For each step ``k`` (the base at ``stands[k]`` = x, y, yaw; the arm's frames at
    ``step_frames[k]``, frame ``grasp`` the grasp frame): which of ``bodies`` body columns the
    robot may touch. Spheres are grouped by frame (``sphere_groups``: first and end index of
    each frame's spheres; ``sphere_link`` names each sphere's frame).

    ``held_boxes`` are in the grasp frame, ``base_boxes`` in the base's frame
    (either may be empty); ``held_box_group[m]`` names the sphere group that must also touch
    for held box ``m`` to mark a body (-1: the box alone), and the groups from
    ``arm_groups`` on are such held spheres (linked to the grasp frame). A body column
    below 0 is never marked (a body to ignore)."""
    steps = step_frames.shape[0]
    out = np.zeros((steps, bodies), dtype=np.bool_)
    box_low = np.empty((boxes.shape[0], 3))
    box_high = np.empty((boxes.shape[0], 3))
    for b in range(boxes.shape[0]):
        box_aabb(boxes[b], box_low[b], box_high[b])
    count = sphere_groups.shape[0]
    bounds = np.zeros((count, 4))  # each group's bounding sphere in its link's frame
    group_parts = np.empty((count, 2), dtype=np.int64)
    total = 0
    for g in range(count):
        _bounding_sphere(
            sphere_groups[g, 0], sphere_groups[g, 1], sphere_centre, sphere_radius, bounds[g]
        )
        group_parts[g, 0] = total
        total += (sphere_groups[g, 1] - sphere_groups[g, 0] + PART_SIZE - 1) // PART_SIZE
        group_parts[g, 1] = total
    parts = np.empty((total, 2), dtype=np.int64)  # first and end sphere of each part
    part_bounds = np.zeros((total, 4))
    for g in range(count):
        first = sphere_groups[g, 0]
        for q in range(group_parts[g, 0], group_parts[g, 1]):
            parts[q, 0] = first
            parts[q, 1] = min(first + PART_SIZE, sphere_groups[g, 1])
            _bounding_sphere(parts[q, 0], parts[q, 1], sphere_centre, sphere_radius, part_bounds[q])
            first = parts[q, 1]
    frames = np.empty((step_frames.shape[1], 4, 4))
    group_world = np.empty((count, 4))
    placed = np.zeros(total, dtype=np.int64)
    centres = np.empty((sphere_link.shape[0], 3))
    state = (frames, group_world, placed, centres, np.empty(3), np.empty((total, 4)))
    model = (sphere_link, sphere_centre, sphere_radius, parts, group_parts, part_bounds)
    stand_frame = np.eye(4)
    moving = np.empty((held_boxes.shape[0] + base_boxes.shape[0], 16))
    box_group = np.full(moving.shape[0], -1, dtype=np.int64)
    box_group[: held_boxes.shape[0]] = held_box_group
    work = (
        np.empty(3),
        np.empty(3),
        np.empty((moving.shape[0], 3)),
        np.empty((moving.shape[0], 3)),
        np.empty(3),
        np.empty(3),
        np.empty(16),
        np.empty(3),
    )
    for k in range(steps):
        x, y, yaw = stands[k, 0], stands[k, 1], stands[k, 2]
        c, s = math.cos(yaw), math.sin(yaw)
        frames[:] = step_frames[k]
        for g in range(count):
            link = sphere_link[sphere_groups[g, 0]]
            for r in range(3):
                group_world[g, r] = (
                    frames[link, r, 0] * bounds[g, 0]
                    + frames[link, r, 1] * bounds[g, 1]
                    + frames[link, r, 2] * bounds[g, 2]
                    + frames[link, r, 3]
                )
            group_world[g, 3] = bounds[g, 3]
        placed[:] = 0
        for m in range(held_boxes.shape[0]):
            place_box(frames[grasp], held_boxes[m], moving[m])
        stand_frame[0, 0], stand_frame[0, 1], stand_frame[1, 0], stand_frame[1, 1] = c, -s, s, c
        stand_frame[0, 3], stand_frame[1, 3] = x, y
        for m in range(base_boxes.shape[0]):
            place_box(stand_frame, base_boxes[m], moving[held_boxes.shape[0] + m])
        _mark_step(
            k,
            state,
            model,
            arm_groups,
            moving,
            box_group,
            boxes,
            box_low,
            box_high,
            cylinders,
            out,
            work,
        )
    return out
