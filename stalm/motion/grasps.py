"""Where a gripper takes an object and where an object may be put down.

Shared by the operators' samplers (``stalm.domain``) and the occlusion predicates
(``stalm.predicates``), which must sample grasps and placements exactly as PICK and PLACE do.
"""

from __future__ import annotations

import math

import numpy as np

from stalm.geometry.transforms import (
    Pose3,
    gripper_rotation,
    matrix_from_quat,
    quat_from_matrix,
    se2_to_world,
    wrap_angle,
)
from stalm.world.spec import GRILL_HANDLE_REACH, ObjectSpec, RegionSpec
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
    return [(0.0, 0.0, min(obj.height / 2, 0.09))]


def nearest_grasp_point(
    obj: ObjectSpec, pose: ObjectPose, base: tuple[float, float, float]
) -> tuple[float, float, float]:
    """The object's grasp point nearest the standing pose, in world coordinates."""
    best: tuple[float, float, float] | None = None
    best_distance = math.inf
    for gx, gy, gz in grasp_points(obj):
        wx, wy = se2_to_world((pose.x, pose.y, pose.yaw), gx, gy)
        distance = math.hypot(wx - base[0], wy - base[1])
        if distance < best_distance - 1e-9:
            best, best_distance = (wx, wy, pose.z + gz), distance
    assert best is not None
    return best


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
