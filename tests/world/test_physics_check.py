"""The physics check of a plan: real plans pass it, plans that make an object fall fail it,
naming the step and the object, and ``stalm replay --physics`` says so in one line."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.geometry.transforms import se2_to_world
from stalm.trial.replay import replay_result_json
from stalm.world.physics_check import (
    MASS_KG,
    TOLERANCE_DEG,
    TOLERANCE_M,
    ObjectDrift,
    centre_of_mass,
    check_physics,
    unsettled_objects,
)
from stalm.world.state import ObjectPose, State
from tests.cli_runner import run_cli

TESTS = Path(__file__).parents[1]
P2_RESULT = TESTS / "planners" / "data" / "p2_result.json"
P5_RESULT = TESTS / "trial" / "data" / "p5_result.json"
PLACE_BOTTLE2 = 3
"""``states[3]`` of the P2 record: bottle2 just placed on counter1."""


def _replayed(problem, record: Path):
    return replay_result_json(problem, json.loads(record.read_text()))


@pytest.mark.parametrize(("name", "record"), [("P2", P2_RESULT), ("P5", P5_RESULT)])
def test_a_real_plan_keeps_every_object_where_it_put_it(problems, name, record) -> None:
    replay = _replayed(problems[name], record)
    assert replay.reached_goal
    from stalm import api

    report = api.check_physics(problems[name], replay.states, [str(a) for a in replay.actions])
    assert isinstance(report, api.PhysicsReport)
    assert report.passed and report.failure_line() is None
    assert len(report.steps) == len(replay.states)  # the initial state, then each action
    assert report.steps[0].label == "the initial state"
    assert [s.label for s in report.steps[1:]] == [str(a) for a in replay.actions]
    for step in report.steps:
        assert step.beyond is None
        assert step.largest_move is not None and step.largest_tilt is not None
        assert step.largest_move.displacement_m < 1e-3  # a real plan: well within 1 cm
        assert step.largest_tilt.tilt_deg < 0.1


def _over_the_edge(problem, state: State, name: str) -> State:
    """``state`` with ``name`` standing on counter1's side edge, its axis 0.6 radius beyond it:
    its centre of mass is over the void."""
    counter = problem.spec.region("counter1")
    radius = problem.spec.object(name).radius
    assert radius is not None
    x, y = se2_to_world((*counter.center, counter.yaw), 0.0, counter.size[1] / 2 + 0.6 * radius)
    return state.with_changes(poses={name: ObjectPose.make(x, y, counter.top, 0.0)})


def test_an_object_placed_half_over_an_edge_fails_the_check_by_name(problems) -> None:
    problem = problems["P2"]
    replay = _replayed(problem, P2_RESULT)
    states = list(replay.states[: PLACE_BOTTLE2 + 1])
    states[PLACE_BOTTLE2] = _over_the_edge(problem, states[PLACE_BOTTLE2], "bottle2")
    report = check_physics(problem, states, [str(a) for a in replay.actions])
    assert not report.passed
    failed = report.failure
    assert failed is not None and failed.step == PLACE_BOTTLE2 and failed.beyond is not None
    assert failed.beyond.obj == "bottle2"
    assert failed.beyond.displacement_m > TOLERANCE_M or failed.beyond.tilt_deg > TOLERANCE_DEG
    line = report.failure_line()
    assert line is not None and "step 3 (place(bottle2, on, counter1))" in line
    assert "bottle2" in line and "\n" not in line
    assert all(step.beyond is None for step in report.steps[:PLACE_BOTTLE2])


@pytest.mark.parametrize("name", ["P1", "P2", "P3", "P4", "P5", "P6"])
def test_every_shipped_problem_rests_where_its_file_puts_it(problems, name) -> None:
    assert unsettled_objects(problems[name]) == ()


def test_an_initial_state_with_an_object_over_an_edge_names_it(problems) -> None:
    problem = problems["P2"]
    state = _over_the_edge(problem, problem.initial_state, "bottle2")
    floating = state.pose("bottle1")
    state = state.with_changes(
        poses={"bottle1": ObjectPose.make(floating.x, floating.y, floating.z + 0.2, 0.0)}
    )
    unsettled = unsettled_objects(problem, state)
    # the furthest beyond first: bottle2 fell off the counter, bottle1 onto its table
    assert [drift.obj for drift in unsettled] == ["bottle2", "bottle1"]
    assert unsettled[1].displacement_m == pytest.approx(0.2, abs=0.01)
    with pytest.raises(StalmError, match="unsettled_objects: tolerance_m must be a positive"):
        unsettled_objects(problem, tolerance_m=0.0)


def test_problems_file_warns_of_an_object_that_does_not_rest(monkeypatch, capsys, problems) -> None:
    """The command's side of the check: each unsettled object is one warning line naming the
    file and the object; the real check is the test above."""
    from stalm.world import physics_check

    def unsettled_double(problem, state=None, **terms):
        return (ObjectDrift("bottle1", 0.034, 61.5),)

    monkeypatch.setattr(physics_check, "unsettled_objects", unsettled_double)
    path = problems["P2"].source
    assert run_cli(monkeypatch, "problems", "--file", str(path)) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert (
        f"warning: {path}: 'bottle1' does not rest where the file puts it: under gravity it "
        "moved 3.4 cm and tilted 61.5 deg in 1 s"
    ) in err


def test_an_object_left_floating_falls_and_fails(problems) -> None:
    problem = problems["P2"]
    replay = _replayed(problem, P2_RESULT)
    states = list(replay.states[: PLACE_BOTTLE2 + 1])
    placed = states[PLACE_BOTTLE2].pose("bottle2")
    floating = ObjectPose.make(placed.x, placed.y, placed.z + 0.05, placed.yaw)
    states[PLACE_BOTTLE2] = states[PLACE_BOTTLE2].with_changes(poses={"bottle2": floating})
    report = check_physics(problem, states)
    failed = report.failure
    assert failed is not None and failed.beyond is not None
    assert failed.step == PLACE_BOTTLE2 and failed.label == "action 3"  # no labels given
    assert failed.beyond.obj == "bottle2"
    assert failed.beyond.displacement_m == pytest.approx(0.05, abs=0.005)  # fell to the top


def test_the_tolerance_decides(problems) -> None:
    """The same tiny creep passes at the default tolerance and fails at a tolerance below it."""
    problem = problems["P2"]
    replay = _replayed(problem, P2_RESULT)
    states = replay.states[:2]
    assert check_physics(problem, states).passed
    strict = check_physics(problem, states, tolerance_m=1e-9, tolerance_deg=1e-9)
    assert not strict.passed and strict.failure is not None and strict.failure.step == 0
    assert strict.failure_line() is not None and "the initial state" in str(strict.failure_line())


def test_the_centre_of_mass_is_the_shapes_centroid(problems) -> None:
    spec = problems["P5"].spec
    grill = next(obj for obj in spec.objects if obj.shape == "grill")
    can = next(obj for obj in spec.objects if obj.shape == "cylinder")
    assert can.height is not None and grill.size is not None
    assert centre_of_mass(can) == (0.0, 0.0, can.height / 2)
    z, half = centre_of_mass(grill)[2], grill.size[2] / 2
    assert min(half, grill.handle_z) < z < max(half, grill.handle_z)  # handles pull it a little
    assert abs(z - half) < 0.01
    assert set(MASS_KG) == {"cylinder", "disc", "grill", "box"}
    assert all(mass > 0 and math.isfinite(mass) for mass in MASS_KG.values())


def _record_with(tmp_path: Path, change) -> Path:
    data = json.loads(P2_RESULT.read_text())
    path = tmp_path / "p2.json"
    path.write_text(json.dumps(change(data)))
    return path


def test_replay_physics_passes_a_real_record(monkeypatch, capsys, tmp_path: Path) -> None:
    record = _record_with(tmp_path, lambda data: data)
    assert run_cli(monkeypatch, "replay", str(record), "--physics") == 0
    out = capsys.readouterr().out
    assert "the goal is reached" in out
    assert "physics check passed" in out and "place(salter, right_of, bottle1)" in out


def test_replay_physics_fails_in_one_line_naming_step_and_object(
    monkeypatch, capsys, tmp_path: Path
) -> None:
    """A real plan held to a tolerance below the micrometres objects creep while settling
    fails at its first step, in one line naming the step and the object; ``stalm replay``
    validates a record so that a plan it accepts cannot leave an object floating or over an
    edge, which is why the topple cases above build their states directly."""
    record = _record_with(tmp_path, lambda data: data)
    code = run_cli(monkeypatch, "replay", str(record), "--physics", "--physics-tolerance-m", "1e-9")
    assert code == 1
    out = capsys.readouterr().out
    failures = [line for line in out.splitlines() if "physics check fails" in line]
    assert len(failures) == 1
    assert "at step 0 (the initial state)" in failures[0] and " moved " in failures[0]
    assert any(name in failures[0] for name in ("bottle1", "bottle2", "bottle3", "salter"))


def test_replay_physics_tolerances_must_be_positive(monkeypatch, capsys, tmp_path: Path) -> None:
    record = _record_with(tmp_path, lambda data: data)
    bad = run_cli(monkeypatch, "replay", str(record), "--physics", "--physics-tolerance-deg", "0")
    assert bad == 2 and "--physics-tolerance-deg" in capsys.readouterr().err
    bad = run_cli(monkeypatch, "replay", str(record), "--physics-tolerance-m", "nan")
    assert bad == 2 and "--physics-tolerance-m" in capsys.readouterr().err


def test_a_replaced_state_keeps_its_other_fields(problems) -> None:
    """The edge helper above moves one object and nothing else (so the failure is its)."""
    replay = _replayed(problems["P2"], P2_RESULT)
    state = replay.states[PLACE_BOTTLE2]
    moved = _over_the_edge(problems["P2"], state, "bottle2")
    assert dataclasses.replace(moved, poses=state.poses) == state
    assert moved.pose("bottle2") != state.pose("bottle2")


def test_a_step_where_nothing_rests_is_said_so(capsys) -> None:
    """A one-object world whose object is in the hand has nothing to measure at that step."""
    from stalm.cli.physics_report import print_physics
    from stalm.world.physics_check import PhysicsReport, StepCheck

    held = StepCheck(1, "pick(can)", None, None, None)
    print_physics(PhysicsReport((held,), TOLERANCE_M, TOLERANCE_DEG, 1.0))
    out = capsys.readouterr().out
    assert "step 1 (pick(can)): no object rests" in out and "physics check passed" in out


def test_solve_physics_records_the_check_and_the_record_replays_it(
    monkeypatch, capsys, tmp_path: Path
) -> None:
    """``stalm solve P2 --physics``: the solved plan is settled, printed and recorded; the
    record then passes ``stalm replay --physics`` with the same steps."""
    record = tmp_path / "p2.json"
    code = run_cli(monkeypatch, "solve", "P2", "--physics", "--json", str(record), "--quiet")
    assert code == 0
    assert "physics check passed" in capsys.readouterr().out
    data = json.loads(record.read_text())
    physics = data["physics"]
    assert physics["passed"] is True and physics["failure"] is None
    assert physics["tolerance_m"] == TOLERANCE_M and physics["tolerance_deg"] == TOLERANCE_DEG
    assert len(physics["steps"]) == data["plan_length"] + 1
    assert all(step["largest_move"]["m"] < TOLERANCE_M for step in physics["steps"])
    assert run_cli(monkeypatch, "replay", str(record), "--physics") == 0
    assert "physics check passed" in capsys.readouterr().out


def test_an_experiment_records_the_check_with_physics(monkeypatch, tmp_path: Path) -> None:
    """``stalm experiment --physics``: each solved trial's record carries the check; the
    trial's key is the one it has without (the check changes nothing the planner does)."""
    args = ("experiment", "table2", "--problems", "P2", "--planners", "stalm-symbolic")
    checked, plain = tmp_path / "physics.jsonl", tmp_path / "plain.jsonl"
    assert run_cli(monkeypatch, *args, "--trials", "1", "--physics", "--results", str(checked)) == 0
    [record] = [json.loads(line) for line in checked.read_text().splitlines()]
    assert record["success"] is True
    assert record["physics"]["passed"] is True and record["physics"]["failure"] is None
    assert len(record["physics"]["steps"]) == record["plan_length"] + 1
    assert run_cli(monkeypatch, *args, "--trials", "1", "--results", str(plain)) == 0
    [without] = [json.loads(line) for line in plain.read_text().splitlines()]
    assert "physics" not in without and without["key"] == record["key"]


@pytest.mark.parametrize(
    ("argument", "value"),
    [
        ("tolerance_m", 0.0),
        ("tolerance_deg", -1.0),
        ("tolerance_m", math.nan),
        ("settle_seconds", 0.0),
    ],
)
def test_the_api_refuses_a_tolerance_or_settling_time_that_is_no_number_of_its_kind(
    problems, argument, value
) -> None:
    from stalm.errors import StalmError

    problem = problems["P2"]
    with pytest.raises(StalmError, match=f"check_physics: {argument} must be"):
        check_physics(problem, (problem.initial_state,), **{argument: value})
