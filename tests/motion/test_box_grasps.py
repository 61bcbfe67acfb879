"""Grasps from shape: a box's grasps come from its size and the gripper's opening (every draw
fits between the fingers), a round object's stay what they were, and the engines agree on a
scene of boxes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from stalm.domain.actions import Pick, Place
from stalm.domain.mdp import Domain
from stalm.domain.outcome import Infeasibility
from stalm.domain.params import PickParams
from stalm.domain.samplers import SamplerSettings
from stalm.geometry.transforms import gripper_rotation, matrix_from_quat
from stalm.motion.grasps import (
    PITCH_RANGE,
    YAW_RANGE,
    closing_width,
    grasp_window,
    nearest_grasp_point,
)
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.samples import PredicateSettings
from stalm.world import robot as robot_model
from stalm.world.object_spec import ObjectSpec
from stalm.world.problem import Problem, load_problem
from stalm.world.spec import ProblemSpec
from stalm.world.state import ObjectPose

BOX1 = Path(__file__).resolve().parents[2] / "stalm" / "problems" / "box1.yaml"
GAP = robot_model.GRIPPER_GAP


def _box(size: tuple[float, float, float]) -> ObjectSpec:
    return ObjectSpec.model_validate(
        {"name": "b", "shape": "box", "size": size, "on": "r", "at": (0.0, 0.0)}
    )


def _width_across_fingers(obj: ObjectSpec, yaw: float, approach: float, pitch: float) -> float:
    """The box's extent along the gripper's closing axis (its y), from the full rotation."""
    closing = gripper_rotation(approach, pitch)[:, 1]
    c, s = math.cos(yaw), math.sin(yaw)
    assert obj.size is not None
    axes = ((c, s, 0.0), (-s, c, 0.0), (0.0, 0.0, 1.0))
    return sum(
        size * abs(float(np.dot(closing, axis))) for size, axis in zip(obj.size, axes, strict=True)
    )


def test_every_box_grasp_drawn_fits_between_the_fingers() -> None:
    rng = np.random.default_rng(7)
    windows = 0
    for _ in range(400):
        size = tuple(float(v) for v in rng.uniform(0.02, 0.3, 3))
        obj = _box(size)  # type: ignore[arg-type]
        pose = ObjectPose.make(0.7, 0.0, 1.0, float(rng.uniform(-math.pi, math.pi)))
        stand = (0.0, 0.0, float(rng.uniform(-0.3, 0.3)))
        window = grasp_window(obj, pose, stand, PITCH_RANGE, YAW_RANGE)
        if min(size[0], size[1]) > GAP:
            assert window is None
        if window is None:
            continue
        windows += 1
        assert YAW_RANGE[0] <= window.yaw_range[0] <= window.yaw_range[1] <= YAW_RANGE[1]
        for _ in range(20):
            pitch = float(rng.uniform(*window.pitch_range))
            yaw = float(rng.uniform(*window.yaw_range))
            approach = stand[2] + yaw
            width = _width_across_fingers(obj, pose.yaw, approach, pitch)
            assert width <= GAP + 1e-9
            assert closing_width(obj, pose.yaw, approach) == pytest.approx(width, abs=1e-9)
    assert windows > 100


def test_a_tall_box_is_taken_from_the_side_near_its_face_a_low_one_from_above() -> None:
    stand = (0.0, 0.0, 0.0)
    crate = _box((0.3, 0.07, 0.14))  # long away from the robot, narrow across
    window = grasp_window(crate, ObjectPose.make(0.7, 0.0, 1.0, 0.0), stand, PITCH_RANGE, YAW_RANGE)
    assert window is not None
    assert window.pitch_range == PITCH_RANGE
    # the grasp frame sits the palm's depth inside the near face, at half the box's height
    assert window.local == pytest.approx((-0.15 + robot_model.GRIPPER_PALM_DEPTH, 0.0, 0.07))
    assert window.point == pytest.approx((0.7 - 0.15 + robot_model.GRIPPER_PALM_DEPTH, 0.0, 1.07))
    tray = _box((0.07, 0.2, 0.03))
    ahead = ObjectPose.make(0.7, 0.0, 1.0, 0.0)
    assert grasp_window(tray, ahead, stand, PITCH_RANGE, YAW_RANGE) is None  # 0.2 m across
    turned = ObjectPose.make(0.7, 0.0, 1.0, math.pi / 2)
    window = grasp_window(tray, turned, stand, PITCH_RANGE, YAW_RANGE)
    assert window is not None
    assert window.pitch_range == pytest.approx((math.pi / 4, math.pi / 2))
    assert window.local == pytest.approx((0.0, 0.0, 0.015))
    # the fingers close across its 0.07 m; turning them widens the tray between them fast
    assert window.yaw_range[1] - window.yaw_range[0] < 0.2


def test_a_box_whose_narrow_sides_face_away_from_the_robot_has_no_grasp() -> None:
    crate = _box((0.3, 0.07, 0.14))
    turned = ObjectPose.make(0.7, 0.0, 1.0, math.pi / 2)
    assert grasp_window(crate, turned, (0.0, 0.0, 0.0), PITCH_RANGE, YAW_RANGE) is None


def test_a_can_wider_than_the_gripper_opens_has_no_grasp() -> None:
    mug = ObjectSpec.model_validate(
        {
            "name": "mug",
            "shape": "cylinder",
            "radius": 0.041,
            "height": 0.1,
            "on": "r",
            "at": (0, 0),
        }
    )
    pose = ObjectPose.make(0.7, 0.0, 1.0, 0.0)
    assert grasp_window(mug, pose, (0.0, 0.0, 0.0), PITCH_RANGE, YAW_RANGE) is None
    narrower = mug.model_copy(update={"radius": 0.038})
    assert grasp_window(narrower, pose, (0.0, 0.0, 0.0), PITCH_RANGE, YAW_RANGE) is not None


def test_a_cylinders_grasp_is_what_it_was(problems: dict[str, Problem]) -> None:
    """The window of a round object is its nearest grasp point with the ranges as given, so
    its draws (and P1-P6's golden files) are unchanged."""
    for problem in problems.values():
        state = problem.initial_state
        for obj in problem.spec.objects:
            pose = state.pose(obj.name)
            stand = problem.spec.region(obj.on).base_pose
            window = grasp_window(obj, pose, stand, PITCH_RANGE, YAW_RANGE)
            assert window is not None
            assert window.point == nearest_grasp_point(obj, pose, stand)
            assert (window.pitch_range, window.yaw_range) == (PITCH_RANGE, YAW_RANGE)


def test_a_picked_box_is_held_across_faces_the_gripper_opens_for() -> None:
    problem = load_problem(BOX1)
    domain = Domain.create(problem)
    try:
        rng = np.random.default_rng(3)
        for name in ("crackers", "crate"):
            params = domain.samplers.pick(problem.initial_state, Pick(name), rng)
            assert isinstance(params, PickParams), params
            obj = problem.spec.object(name)
            assert obj.size is not None
            # the object's frame in the gripper's: the gripper's closing axis in the object's
            closing = matrix_from_quat(params.grasp.orientation)[1, :]
            width = sum(s * abs(float(a)) for s, a in zip(obj.size, closing, strict=True))
            assert width <= GAP + 1e-6, name
        # the crate lying across the table, its long side toward the robot: no pair of faces
        # the gripper opens for faces it within PICK's yaw range
        across = ObjectPose.make(-2.2, -1.0, 1.0, 3 * math.pi / 2)
        turned = problem.initial_state.with_changes(poses={"crate": across})
        failure = domain.samplers.pick(turned, Pick("crate"), rng)
        assert isinstance(failure, Infeasibility)
        assert "no grasp of 'crate' fits" in failure.detail
    finally:
        domain.close()


def test_both_engines_give_the_same_predicates_on_boxes() -> None:
    problem = load_problem(BOX1)
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
    assert "PickOccludedBy(cereal, crackers)" in names
    assert "PlaceOccludedBy(can, on, ledge, crate)" in names


def test_pddlstreams_grasp_of_a_box_fits_and_a_too_wide_one_has_none() -> None:
    from stalm.planners.pddlstream.streams import StreamGeometry

    problem = load_problem(BOX1)
    data = problem.spec.model_dump(mode="json")
    data["objects"][2]["size"] = [0.3, 0.09, 0.14]  # the crate, now too wide on every side
    wide = Problem(ProblemSpec.model_validate(data), "wide")
    for case, expect_grasp in ((problem, True), (wide, False)):
        domain = Domain.create(case)
        try:
            geometry = StreamGeometry(domain)
            rng = np.random.default_rng(5)
            value = geometry.sample_grasp("crate", rng)
            if not expect_grasp:
                assert value is None
                failure = domain.samplers.pick(case.initial_state, Pick("crate"), rng)
                assert isinstance(failure, Infeasibility)
                assert failure.detail.startswith("'crate': it is 0.09 m across at its narrowest")
                continue
            assert value is not None
            crate = case.spec.object("crate")
            assert crate.size is not None
            closing = matrix_from_quat(value.grasp.orientation)[1, :]
            width = sum(s * abs(float(a)) for s, a in zip(crate.size, closing, strict=True))
            assert width <= GAP + 1e-6
            assert value.point == pytest.approx((-0.15 + robot_model.GRIPPER_PALM_DEPTH, 0, 0.07))
            assert geometry.sample_grasp("can", rng) is not None  # round: as before
        finally:
            domain.close()


def test_a_low_box_is_picked_from_above_and_put_down() -> None:
    problem = load_problem(BOX1)
    data = problem.spec.model_dump(mode="json")
    data["objects"][0].update(size=[0.06, 0.16, 0.04], at=[-0.12, 0.0])  # a low packet
    low = Problem(ProblemSpec.model_validate(data), "low")
    domain = Domain.create(low)
    try:
        rng = np.random.default_rng(0)
        drawn, picked = domain.sample_and_step(low.initial_state, Pick("crackers"), rng)
        assert picked.feasible and drawn is not None
        assert isinstance(drawn.params, PickParams)
        assert drawn.params.pitch > math.pi / 4  # from above
        _, placed = domain.sample_and_step(picked.state, Place("crackers", "on", "table"), rng)
        assert placed.feasible, placed.failure
    finally:
        domain.close()


def test_both_engines_draw_the_same_sampler_outcomes_on_boxes() -> None:
    """ψ with either engine on BOX1: the same κ (or failure and blockers) for every legal
    action of its first states, from the same seed (a held box is tested as its box)."""
    from tests.test_behaviour_unchanged import draw_record

    rows = []
    for engine in ("pybullet", "batched"):
        domain = Domain.create(load_problem(BOX1), sampler_settings=SamplerSettings(engine=engine))
        try:
            rows.append(draw_record(domain))
        finally:
            domain.close()
    assert rows[0] == rows[1]
    assert any(row["action"] == "pick(crate)" and row["feasible"] for row in rows[0])
