"""Grasps of mesh objects and the batched engine's cover of them: every grasp drawn fits the
hull between the fingers (its support-function width across the closing axis), and on the
scene of meshes the batched engine (a box around each convex piece) gives the reference's
literals, motion hits and sampler outcomes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from stalm.domain.actions import Pick
from stalm.domain.mdp import Domain
from stalm.domain.params import PickParams
from stalm.domain.samplers import SamplerSettings
from stalm.geometry.transforms import gripper_rotation, matrix_from_quat
from stalm.motion.grasps import PITCH_RANGE, YAW_RANGE, grasp_window
from stalm.motion.scene_primitives import MOST_PIECE_BOXES, object_boxes
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.samples import PredicateSettings
from stalm.world import robot as robot_model
from stalm.world.grip_widths import hull_widths
from stalm.world.mesh_pieces import object_pieces
from stalm.world.problem import load_problem
from stalm.world.state import ObjectPose

MESH1 = Path(__file__).resolve().parents[2] / "stalm" / "problems" / "mesh1.yaml"
GAP = robot_model.GRIPPER_GAP


def _width_across_fingers(points: np.ndarray, object_yaw: float, approach: float, pitch: float):
    """The hull's extent along the gripper's closing axis, from the full rotation."""
    closing = gripper_rotation(approach, pitch)[:, 1]
    assert abs(closing[2]) < 1e-12  # the closing axis stays level
    angle = math.atan2(closing[1], closing[0]) - object_yaw
    return float(hull_widths(points, np.array([angle]))[0])


def test_every_mesh_grasp_drawn_fits_between_the_fingers() -> None:
    problem = load_problem(MESH1)
    rng = np.random.default_rng(11)
    windows = 0
    for obj in problem.spec.objects:
        points = obj.outline.points
        for _ in range(60):
            pose = ObjectPose.make(0.7, 0.0, 1.0, float(rng.uniform(-math.pi, math.pi)))
            stand = (0.0, 0.0, float(rng.uniform(-0.3, 0.3)))
            window = grasp_window(obj, pose, stand, PITCH_RANGE, YAW_RANGE)
            if window is None:
                continue
            windows += 1
            assert YAW_RANGE[0] <= window.yaw_range[0] <= window.yaw_range[1] <= YAW_RANGE[1]
            for _ in range(20):
                pitch = float(rng.uniform(*window.pitch_range))
                yaw = float(rng.uniform(*window.yaw_range))
                width = _width_across_fingers(points, pose.yaw, stand[2] + yaw, pitch)
                assert width <= GAP + 1e-9, obj.name
    assert windows > 120


def test_a_low_mesh_is_taken_from_above_a_tall_one_from_the_side() -> None:
    problem = load_problem(MESH1)
    stand = (0.0, 0.0, 0.0)
    ahead = ObjectPose.make(0.7, 0.0, 1.0, 0.0)
    brick = problem.spec.object("brick")  # 0.035 m high
    window = grasp_window(brick, ahead, stand, PITCH_RANGE, YAW_RANGE)
    assert window is not None
    assert window.pitch_range == pytest.approx((math.pi / 4, math.pi / 2))
    toy = problem.spec.object("toy")  # 0.093 m high, 0.033 m along x, 0.092 m along y
    facing = ObjectPose.make(0.7, 0.0, 1.0, math.pi / 2)  # its narrow side across the fingers
    window = grasp_window(toy, facing, stand, PITCH_RANGE, YAW_RANGE)
    assert window is not None
    assert window.pitch_range == PITCH_RANGE
    # taken straight ahead (along its -y) at half its height, the palm's depth inside its near
    # side (along the window's middle yaw, a fraction of a degree off straight ahead)
    near = -float(toy.outline.points[:, 1].max())
    assert -window.local[1] == pytest.approx(near + robot_model.GRIPPER_PALM_DEPTH, abs=1e-3)
    assert window.local[2] == pytest.approx(toy.half_extents[2])
    assert window.yaw_range[0] < 0.0 < window.yaw_range[1]
    # turned a quarter, its 0.092 m is across the fingers straight ahead: it is taken only
    # turned well to the side, where its narrow depth comes between them
    across = ObjectPose.make(0.7, 0.0, 1.0, 0.0)
    turned = grasp_window(toy, across, stand, PITCH_RANGE, YAW_RANGE)
    assert turned is not None
    assert min(abs(turned.yaw_range[0]), abs(turned.yaw_range[1])) > math.radians(30)


def test_a_meshs_boxes_hold_its_pieces() -> None:
    """A box per convex piece, or one box around them all for a mesh of more than
    MOST_PIECE_BOXES pieces (MESH1's LEGO brick, 42 pieces from V-HACD)."""
    problem = load_problem(MESH1)
    counts = []
    for obj in problem.spec.objects:
        pieces = object_pieces(obj).vertices
        boxes = object_boxes(obj)
        counts.append(len(pieces))
        if len(pieces) > MOST_PIECE_BOXES:
            assert len(boxes) == 1
            boxes = boxes * len(pieces)
        assert len(boxes) == len(pieces)
        for vertices, (centre, half) in zip(pieces, boxes, strict=True):
            assert np.all(np.abs(vertices - np.asarray(centre)) < np.asarray(half)), obj.name
    assert max(counts) > MOST_PIECE_BOXES >= min(counts)  # both covers are tested


def test_a_picked_mesh_is_held_across_a_width_the_gripper_opens_for() -> None:
    problem = load_problem(MESH1)
    domain = Domain.create(problem)
    try:
        rng = np.random.default_rng(3)
        for name in ("brick", "plate_right"):
            params = domain.samplers.pick(problem.initial_state, Pick(name), rng)
            assert isinstance(params, PickParams), params
            points = problem.spec.object(name).outline.points
            # the gripper's closing axis in the object's frame
            closing = matrix_from_quat(params.grasp.orientation)[1, :]
            across = points @ closing
            assert float(across.max() - across.min()) <= GAP + 1e-6, name
    finally:
        domain.close()


def test_both_engines_give_the_same_predicates_on_meshes() -> None:
    problem = load_problem(MESH1)
    domain = Domain.create(problem)
    try:
        reference, batched = (
            PredicateEngine(
                problem, domain.sim, domain.base_planner, PredicateSettings(engine=engine)
            ).compute(problem.initial_state)
            for engine in ("pybullet", "batched")
        )
    finally:
        domain.close()
    assert batched.literals == reference.literals
    assert {k: m.hits for k, m in batched.base.items()} == {
        k: m.hits for k, m in reference.base.items()
    }
    for key, record in reference.picks.items():
        assert [m.hits for m in batched.picks[key].motions] == [m.hits for m in record.motions]
    for key, samples in reference.placements.items():
        assert [s.motion.hits for s in batched.placements[key]] == [s.motion.hits for s in samples]
    names = {str(literal) for literal in batched.literals}
    assert "PickOccludedBy(toy, plate_left)" in names
    assert "PickOccludedBy(toy, plate_right)" in names


@pytest.mark.slow
def test_both_engines_draw_the_same_sampler_outcomes_on_meshes() -> None:
    """ψ with either engine on MESH1: the same κ (or failure and blockers) for every legal
    action of its first states, from the same seed (a held mesh is tested as its boxes)."""
    from tests.test_behaviour_unchanged import draw_record

    rows = []
    for engine in ("pybullet", "batched"):
        domain = Domain.create(load_problem(MESH1), sampler_settings=SamplerSettings(engine=engine))
        try:
            rows.append(draw_record(domain))
        finally:
            domain.close()
    assert rows[0] == rows[1]
    assert any(row["action"] == "pick(brick)" and row["feasible"] for row in rows[0])
