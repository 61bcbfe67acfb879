"""Where a gripper takes an object and where an object may be put down.

Shared by the operators' samplers (``stalm.domain``) and the occlusion predicates
(``stalm.predicates``), which must sample grasps and placements exactly as PICK and PLACE do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stalm.geometry.transforms import (
    Pose3,
    gripper_rotation,
    matrix_from_quat,
    quat_from_matrix,
    se2_to_world,
    wrap_angle,
)
from stalm.world import robot as robot_model
from stalm.world.grip_widths import hull_widths, too_wide
from stalm.world.object_spec import GRILL_HANDLE_REACH, ObjectSpec
from stalm.world.spec import RegionSpec
from stalm.world.state import ObjectPose

PITCH_RANGE = (0.0, math.radians(45.0))
"""Gripper pitch range of PICK (paper §4.1): 0 is a horizontal approach."""
YAW_RANGE = (math.radians(-60.0), math.radians(60.0))
"""Gripper yaw range of PICK relative to the standing pose (paper §4.1)."""
APPROACH_DISTANCE = 0.08
"""The gripper comes in (and backs out) along its approach axis over this distance (m)."""
LIFT_DISTANCE = 0.05
"""A grasped object is raised this much before the arm folds back (m)."""
PLACE_CLEARANCE = 0.12
"""A held object is lowered onto its placement from this height above it (m)."""


SIDE_GRASP_HEIGHT_CAP = 0.09
"""A side grasp takes an upright object at half its height, but no higher than this (m): a
tall bottle is held low, where the arm reaches it from a counter's standing pose."""
SIDE_GRASP_MIN_HEIGHT = 0.08
"""A box lower than this (m) is taken from above: a side grasp at half its height would put
the palm, which sits outside the box's near face and reaches 3.6 cm either side of the grasp
frame across the fingers' plane (measured in PyBullet), into the surface it rests on."""


@dataclass(frozen=True)
class GraspWindow:
    """Where a gripper takes an object and the angles it may take it at: the grasp point in
    the object's frame and in the world, and PICK's pitch and yaw (relative to the standing
    pose) ranges, inside which every draw is a grasp whose closing width fits the gripper."""

    local: tuple[float, float, float]
    point: tuple[float, float, float]
    pitch_range: tuple[float, float]
    yaw_range: tuple[float, float]


def grasp_window(
    obj: ObjectSpec,
    pose: ObjectPose,
    stand: tuple[float, float, float],
    pitch_range: tuple[float, float],
    yaw_range: tuple[float, float],
    gap: float = robot_model.GRIPPER_GAP,
    palm_depth: float = robot_model.GRIPPER_PALM_DEPTH,
) -> GraspWindow | None:
    """The grasp of ``obj`` resting at ``pose`` that PICK samples from ``stand``; None if no
    grasp fits from there: the object is wider than ``gap`` across every closing direction
    (:func:`~stalm.world.grip_widths.too_wide`), or it is a box turned so that no pair of
    faces narrow enough faces the robot within ``yaw_range``.

    An upright cylinder (and a plate's rim, a grill's handle) fits at every yaw: its grasp is
    its point nearest the stand with the ranges as given. A box is taken across a pair of
    opposite faces: from the side (pitch in ``pitch_range``) if it is tall enough, else from
    above (pitch the same span below vertical). Turning the gripper by ``t`` from square to
    the faces makes the box ``w |cos t| + d |sin t|`` wide across the fingers (width ``w``
    between the faces, depth ``d``), so the yaw range is cut to where that fits ``gap``; of
    the face pairs and approach sides, the widest remaining range is taken (ties: the one most
    straight ahead)."""
    if too_wide(obj, gap) is not None:
        return None
    if obj.shape == "mesh":
        return _mesh_window(obj, pose, stand, pitch_range, yaw_range, gap, palm_depth)
    if not yaw_limited(obj):
        point = nearest_grasp_point(obj, pose, stand)
        local = _nearest_local(obj, pose, stand)
        return GraspWindow(local, point, pitch_range, yaw_range)
    assert obj.size is not None
    sx, sy, sz = obj.size
    side = sz >= SIDE_GRASP_MIN_HEIGHT
    span = pitch_range[1] - pitch_range[0]
    pitches = pitch_range if side else (math.pi / 2 - span, math.pi / 2)
    best: tuple[float, float, tuple[float, float], tuple[float, float, float]] | None = None
    for closing, width, depth in ((0, sx, sy), (1, sy, sx)):
        if width > gap:
            continue
        turn = _fitting_turn(width, depth, gap)
        for sense in (1.0, -1.0):
            # the approach runs along the other horizontal axis, into the face on its far side
            approach = (math.pi / 2 if closing == 0 else 0.0) + (0.0 if sense > 0 else math.pi)
            ahead = wrap_angle(pose.yaw + approach - stand[2])
            for centre in (ahead - 2 * math.pi, ahead, ahead + 2 * math.pi):
                low, high = max(yaw_range[0], centre - turn), min(yaw_range[1], centre + turn)
                if low > high:
                    continue
                key = (high - low, -abs((low + high) / 2))
                if best is None or key > (best[0], best[1]):
                    if side:
                        inset = -depth / 2 + min(depth / 2, palm_depth)
                        z = min(sz / 2, SIDE_GRASP_HEIGHT_CAP)
                    else:
                        inset, z = 0.0, max(sz / 2, sz - palm_depth)
                    local = (0.0, sense * inset, z) if closing == 0 else (sense * inset, 0.0, z)
                    best = (*key, (low, high), local)
    if best is None:
        return None
    _, _, yaws, local = best
    wx, wy = se2_to_world((pose.x, pose.y, pose.yaw), local[0], local[1])
    return GraspWindow(local, (wx, wy, pose.z + local[2]), pitches, yaws)


def yaw_limited(obj: ObjectSpec) -> bool:
    """Does the gripper's yaw around ``obj`` decide whether it fits (a box: its faces differ
    in width, and turning widens it across the fingers), unlike a round object's?"""
    return obj.shape in ("box", "mesh")


MESH_YAW_STEP = math.radians(0.25)
"""The step (radians) at which a mesh's closing width is measured over PICK's yaw range."""


def _mesh_window(
    obj: ObjectSpec,
    pose: ObjectPose,
    stand: tuple[float, float, float],
    pitch_range: tuple[float, float],
    yaw_range: tuple[float, float],
    gap: float,
    palm_depth: float,
) -> GraspWindow | None:
    """A mesh's grasp, as a box's: the widest run of yaws in ``yaw_range`` (ties: the one
    most straight ahead) where the width of its hull across the fingers
    (:func:`~stalm.world.grip_widths.hull_widths`, measured every :data:`MESH_YAW_STEP`) fits
    ``gap`` at every yaw of the run, not only the measured ones; from the side at half its
    height (capped) if it is tall enough, else from above.
    The grasp point is centred across the fingers at the run's middle yaw and, from the side,
    at most ``palm_depth`` behind the mesh's near side, so the palm stays out of it."""
    outline = obj.outline
    points = outline.points
    count = max(2, math.ceil((yaw_range[1] - yaw_range[0]) / MESH_YAW_STEP) + 1)
    yaws = np.linspace(yaw_range[0], yaw_range[1], count)
    approach = yaws + stand[2] - pose.yaw  # the approach direction in the object's frame
    # between two samples the width grows at most 2 r per radian (r: the farthest vertex from
    # the frame's axis), so a yaw within half a step of a sample is at most r * step wider
    slack = float(np.hypot(points[:, 0], points[:, 1]).max()) * (yaws[1] - yaws[0])
    fits = hull_widths(points, approach + math.pi / 2) <= gap - slack
    best: tuple[float, float, int, int] | None = None
    start = None
    for index in range(count + 1):
        if index < count and fits[index]:
            start = index if start is None else start
            continue
        if start is not None:
            low, high = float(yaws[start]), float(yaws[index - 1])
            key = (high - low, -abs((low + high) / 2))
            if best is None or key > best[:2]:
                best = (*key, start, index - 1)
            start = None
    if best is None:
        return None
    low, high = float(yaws[best[2]]), float(yaws[best[3]])
    middle = (low + high) / 2 + stand[2] - pose.yaw
    along = np.array([math.cos(middle), math.sin(middle)])
    across = np.array([-along[1], along[0]])
    depth, width = points[:, :2] @ along, points[:, :2] @ across
    centre = (width.max() + width.min()) / 2
    height = 2 * outline.half_extents[2]
    if height >= SIDE_GRASP_MIN_HEIGHT:
        pitches = pitch_range
        inset = depth.min() + min((depth.max() - depth.min()) / 2, palm_depth)
        z = min(height / 2, SIDE_GRASP_HEIGHT_CAP)
    else:
        span = pitch_range[1] - pitch_range[0]
        pitches = (math.pi / 2 - span, math.pi / 2)
        inset = (depth.max() + depth.min()) / 2
        z = max(height / 2, height - palm_depth)
    lx, ly = inset * along + centre * across
    local = (float(lx), float(ly), float(z))
    wx, wy = se2_to_world((pose.x, pose.y, pose.yaw), local[0], local[1])
    return GraspWindow(local, (wx, wy, pose.z + local[2]), pitches, (low, high))


def _fitting_turn(width: float, depth: float, gap: float) -> float:
    """The largest turn ``t`` in [0, pi/2] from square such that a ``width`` x ``depth``
    rectangle spans at most ``gap`` across the closing direction at every turn up to ``t``."""
    reach = math.hypot(width, depth)
    if reach <= gap:
        return math.pi / 2
    return math.atan2(depth, width) - math.acos(gap / reach)


def closing_width(obj: ObjectSpec, object_yaw: float, approach_yaw: float) -> float:
    """How wide a box spans across the fingers of a gripper approaching along
    ``approach_yaw`` (its closing axis level and square to that yaw) when the box stands
    with ``object_yaw``."""
    assert obj.size is not None
    turn = approach_yaw + math.pi / 2 - object_yaw  # the closing axis in the box's frame
    return obj.size[0] * abs(math.cos(turn)) + obj.size[1] * abs(math.sin(turn))


def _nearest_local(
    obj: ObjectSpec, pose: ObjectPose, base: tuple[float, float, float]
) -> tuple[float, float, float]:
    """The grasp point :func:`nearest_grasp_point` picks, in the object's frame."""
    best: tuple[float, float, float] | None = None
    best_distance = math.inf
    for gx, gy, gz in grasp_points(obj):
        wx, wy = se2_to_world((pose.x, pose.y, pose.yaw), gx, gy)
        distance = math.hypot(wx - base[0], wy - base[1])
        if distance < best_distance - 1e-9:
            best, best_distance = (gx, gy, gz), distance
    assert best is not None
    return best


def grasp_points(obj: ObjectSpec) -> list[tuple[float, float, float]]:
    """Candidate grasp points in the object's frame (origin at its bottom centre)."""
    if obj.shape == "grill":
        assert obj.size is not None
        _, sy, _ = obj.size
        side = sy / 2 + GRILL_HANDLE_REACH * 0.6
        return [(0.0, side, obj.handle_z), (0.0, -side, obj.handle_z)]
    assert obj.radius is not None and obj.height is not None
    if obj.shape == "disc":
        # a plate is taken at its rim from above: the grasp point sits just over the rim
        r, z = obj.radius * 0.85, obj.height + 0.012
        return [(r, 0.0, z), (-r, 0.0, z), (0.0, r, z), (0.0, -r, z)]
    return [(0.0, 0.0, min(obj.height / 2, SIDE_GRASP_HEIGHT_CAP))]


def nearest_grasp_point(
    obj: ObjectSpec, pose: ObjectPose, base: tuple[float, float, float]
) -> tuple[float, float, float]:
    """The object's grasp point nearest the standing pose, in world coordinates."""
    gx, gy, gz = _nearest_local(obj, pose, base)
    wx, wy = se2_to_world((pose.x, pose.y, pose.yaw), gx, gy)
    return (wx, wy, pose.z + gz)


def gripper_target(
    point: tuple[float, float, float], stand_yaw: float, pitch: float, yaw: float
) -> Pose3:
    """The gripper pose at ``point`` with the sampled pitch and yaw (relative to the stand)."""
    return (point, quat_from_matrix(gripper_rotation(stand_yaw + yaw, pitch)))


def sample_grasp_angles(
    rng: np.random.Generator, pitch_range: tuple[float, float], yaw_range: tuple[float, float]
) -> tuple[float, float]:
    """Gripper pitch and yaw drawn uniformly from their ranges (paper §4.1, PICK step 2)."""
    return float(rng.uniform(*pitch_range)), float(rng.uniform(*yaw_range))


def gripper_axis(target: Pose3) -> tuple[float, float, float]:
    """The approach direction (+z of the gripper frame) of a gripper pose."""
    rot = matrix_from_quat(target[1])
    return (float(rot[0, 2]), float(rot[1, 2]), float(rot[2, 2]))


def offset_pose(target: Pose3, backoff: float = 0.0, raise_by: float = 0.0) -> Pose3:
    """``target`` moved back along its approach axis and/or straight up."""
    ax, ay, az = gripper_axis(target)
    x, y, z = target[0]
    return ((x - backoff * ax, y - backoff * ay, z - backoff * az + raise_by), target[1])


def placement_bounds(obj: ObjectSpec, region: RegionSpec, yaw: float) -> tuple[float, float] | None:
    """Half ranges (u, v) over which the object's centre may be drawn on the region's usable
    area so that its footprint stays inside; None if it does not fit at all."""
    hx, hy, _ = obj.half_extents
    rel = wrap_angle(yaw - region.yaw)
    ex = abs(math.cos(rel)) * hx + abs(math.sin(rel)) * hy
    ey = abs(math.sin(rel)) * hx + abs(math.cos(rel)) * hy
    ux, uy = region.usable_size
    half_u, half_v = ux / 2 - ex, uy / 2 - ey
    if half_u < 0 or half_v < 0:
        return None
    return half_u, half_v


def draw_placement(
    obj: ObjectSpec, region: RegionSpec, yaw: float, rng: np.random.Generator
) -> ObjectPose | None:
    """One uniform draw of an upright placement with ``yaw`` on the region's usable area."""
    bounds = placement_bounds(obj, region, yaw)
    if bounds is None:
        return None
    u = float(rng.uniform(-bounds[0], bounds[0]))
    v = float(rng.uniform(-bounds[1], bounds[1]))
    x, y = se2_to_world((*region.center, region.yaw), u, v)
    return ObjectPose.make(x, y, region.top, yaw)
