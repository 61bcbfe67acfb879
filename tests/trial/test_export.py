"""``stalm export``: a result's plan as timed trajectories that keep the robot's limits at every
point, start and end at the plan's waypoints, and carry the grasp, release and door events.

The limits the tests check against are read here from the URDF PyBullet loads (its joints'
``maxVelocity``) and from Franka's documented accelerations, not from the export itself.
``tests/viz/data/p2_steps_result.json`` is a real result: STaLM solving P2, with an OPEN.
``data/p5_result.json`` is ``stalm solve P5 --seed 0 --json`` (15 actions) without its
per-step record (``details``), which the export does not read.
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p
import pybullet_data
import pytest

from stalm.cli.export_commands import default_output
from stalm.errors import StalmError
from stalm.trial.export import (
    BASE_JOINTS,
    EXPORT_FORMAT,
    check_rate,
    export_result,
    limit_violations,
)
from stalm.world.robot_limits import FRANKA_ACCELERATION, panda_limits
from tests.cli_runner import run_cli

RESULT_FILE = Path(__file__).parents[1] / "viz" / "data" / "p2_steps_result.json"
RESULT = json.loads(RESULT_FILE.read_text())
P5_FILE = Path(__file__).parent / "data" / "p5_result.json"
TOLERANCE = 1e-6
"""Relative slack on a limit: float rounding only (the plan is timed at 98% of the limits)."""
POSITION_TOLERANCE = 1e-9
"""How close (rad or m) a trajectory's first and last points are to the plan's waypoints."""


@pytest.fixture(scope="module")
def exported(problems) -> dict[str, Any]:
    data, warnings = export_result(problems["P2"], copy.deepcopy(RESULT), 50.0, "p2.json")
    assert warnings == ()
    return data


def urdf_arm_limits() -> tuple[np.ndarray, np.ndarray]:
    """The Panda's joint velocity limits as PyBullet reads them from the URDF, and Franka's
    accelerations: the limits an exported arm trajectory must keep (the lift's apart)."""
    client = p.connect(p.DIRECT)
    try:
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=client)
        arm = p.loadURDF("franka_panda/panda.urdf", physicsClientId=client)
        velocity = [p.getJointInfo(arm, j, physicsClientId=client)[11] for j in range(7)]
    finally:
        p.disconnect(client)
    return np.array(velocity), np.array(FRANKA_ACCELERATION)


def check_trajectories(exported: dict[str, Any], plan: list[dict[str, Any]]) -> None:
    """Every point within the limits (taken from the URDF), and every motion starting and
    ending at the plan's waypoints (the base's yaw up to a whole turn)."""
    velocity, acceleration = urdf_arm_limits()
    base = panda_limits().base
    lift = exported["limits"]["arm"]
    assert len(exported["trajectories"]) == 2 * len(plan)
    for trajectory in exported["trajectories"]:
        step = plan[trajectory["action"]]
        points = trajectory["points"]
        v = np.array([point["velocities"] for point in points])
        a = np.array([point["accelerations"] for point in points])
        first, last = np.array(points[0]["positions"]), np.array(points[-1]["positions"])
        if trajectory["motion"] == "arm":
            assert trajectory["joint_names"][1:] == [f"panda_joint{i}" for i in range(1, 8)]
            assert np.all(np.abs(v[:, 1:]) <= velocity * (1 + TOLERANCE))
            assert np.all(np.abs(a[:, 1:]) <= acceleration * (1 + TOLERANCE))
            assert np.all(np.abs(v[:, 0]) <= lift["velocity"][0] * (1 + TOLERANCE))
            assert np.all(np.abs(a[:, 0]) <= lift["acceleration"][0] * (1 + TOLERANCE))
            waypoints = step["arm_waypoints"]
            assert first == pytest.approx(waypoints[0], abs=POSITION_TOLERANCE)
            assert last == pytest.approx(waypoints[-1], abs=POSITION_TOLERANCE)
        else:
            assert trajectory["joint_names"] == list(BASE_JOINTS)
            assert np.all(np.linalg.norm(v[:, :2], axis=1) <= base.speed * (1 + TOLERANCE))
            assert np.all(np.linalg.norm(a[:, :2], axis=1) <= base.acceleration * (1 + TOLERANCE))
            assert np.all(np.abs(v[:, 2]) <= base.turn_rate * (1 + TOLERANCE))
            assert np.all(np.abs(a[:, 2]) <= base.turn_acceleration * (1 + TOLERANCE))
            corners = step["base_path"]
            assert first == pytest.approx(corners[0], abs=POSITION_TOLERANCE)
            assert last[:2] == pytest.approx(corners[-1][:2], abs=POSITION_TOLERANCE)
            assert math.remainder(last[2] - corners[-1][2], math.tau) == pytest.approx(
                0.0, abs=POSITION_TOLERANCE
            )
        assert np.abs(v[[0, -1]]).max() < 1e-9  # from rest to rest
        times = [point["time_from_start"] for point in points]
        assert times[0] == 0.0 and times[-1] == pytest.approx(trajectory["duration"])
        assert np.all(np.diff(times) > 0)
    for motion in ("base", "arm"):  # each motion starts where the last of its kind ended
        chain = [t for t in exported["trajectories"] if t["motion"] == motion]
        for before, after in itertools.pairwise(chain):
            end = np.array(before["points"][-1]["positions"])
            start = np.array(after["points"][0]["positions"])
            gap = end - start
            if motion == "base":
                gap[2] = math.remainder(gap[2], math.tau)
            assert np.abs(gap).max() < 1e-6, (before["step"], after["step"], gap)


def test_the_exported_plan_keeps_the_urdf_limits_and_its_waypoints(exported) -> None:
    check_trajectories(exported, RESULT["plan"])
    assert limit_violations(exported, panda_limits()) == []


def test_the_export_names_the_robot_the_problem_and_runs_the_motions_in_order(exported):
    assert exported["format"] == EXPORT_FORMAT and exported["problem"] == "P2"
    assert exported["problem_hash"] == RESULT["problem_hash"] and exported["reached_goal"]
    assert exported["robot"]["urdf"] == "franka_panda/panda.urdf"
    assert exported["robot"]["urdf_sha256"] == panda_limits().urdf_sha256
    clock = 0.0
    for trajectory in exported["trajectories"]:  # base, arm, base, arm... back to back
        assert trajectory["start_time"] == pytest.approx(clock)
        clock += trajectory["duration"]
    assert exported["duration"] == pytest.approx(clock) and clock > 30


def test_the_arm_stops_at_every_waypoint_and_the_events_happen_there(exported) -> None:
    events = exported["events"]
    assert [e["event"] for e in events] == [
        "grasp", "release", "open_door", "grasp", "release",
        "grasp", "release", "grasp", "release",
    ]  # fmt: skip
    arms = [t for t in exported["trajectories"] if t["motion"] == "arm"]
    for event, arm, step in zip(events, arms, RESULT["plan"], strict=True):
        key = {"grasp": "grasp_conf", "release": "place_conf", "open_door": "handle_conf"}
        at = event["time"] - arm["start_time"]
        point = min(arm["points"], key=lambda point: abs(point["time_from_start"] - at))
        assert point["time_from_start"] == pytest.approx(at, abs=1e-9)
        assert point["positions"] == pytest.approx(step[key[event["event"]]], abs=1e-9)
        assert max(abs(v) for v in point["velocities"]) < 1e-9
        for time, waypoint in zip(arm["waypoint_times"], step["arm_waypoints"], strict=True):
            match = [x for x in arm["points"] if abs(x["time_from_start"] - time) < 1e-9]
            assert match and match[0]["positions"] == pytest.approx(waypoint, abs=1e-9)
    grasp, release, door = events[0], events[1], events[2]
    assert grasp["object"] == "bottle1" and grasp["frame"] == "panda_grasptarget"
    assert grasp["grasp"]["position"] == RESULT["plan"][0]["grasp"]["position"]
    assert release["placement"] == RESULT["plan"][1]["placement"]
    assert door["door"] == "kitchen_door" and door["open_yaw"] != door["closed_yaw"]


def test_a_trajectory_over_a_limit_is_found(exported) -> None:
    """The check can fail: the same motions run 10% faster break the limits; a trajectory
    that ends moving, times that stand still and joints of another robot are found too."""
    faster = copy.deepcopy(exported)
    for trajectory in faster["trajectories"]:
        for point in trajectory["points"]:
            point["velocities"] = [1.1 * v for v in point["velocities"]]
            point["accelerations"] = [1.21 * a for a in point["accelerations"]]
    found = limit_violations(faster, panda_limits())
    assert any("base" in f and "speed" in f for f in found)
    assert any(re.search(r"arm\): panda_joint\d velocity [\d.]+ over", f) for f in found)
    assert any(re.search(r"arm\): \w+ acceleration [\d.]+ over", f) for f in found)
    moving = copy.deepcopy(exported)
    moving["trajectories"][0]["points"][-1]["velocities"][0] = 0.01
    moving["trajectories"][1]["points"][1]["time_from_start"] = 0.0
    moving["trajectories"][3]["joint_names"][0] = "torso"
    found = limit_violations(moving, panda_limits())
    assert found[0].endswith("does not start and end at rest")
    assert "times do not increase" in found[1] and "are not the limits'" in found[2]


def test_a_plan_that_does_not_replay_is_not_exported(problems) -> None:
    data = copy.deepcopy(RESULT)
    data["plan"][0]["base_path"][0][0] += 0.5  # the drive starts where the robot is not
    with pytest.raises(StalmError, match="step 1 of the plan fails when it is replayed"):
        export_result(problems["P2"], data)


def test_a_plan_that_stops_before_the_goal_is_exported_with_a_warning(problems) -> None:
    data = copy.deepcopy(RESULT)
    data["plan"] = data["plan"][:2]
    exported, warnings = export_result(problems["P2"], data, rate=10.0)
    assert not exported["reached_goal"] and len(exported["trajectories"]) == 4
    assert warnings == ("the plan does not reach the goal (the plan ends before the goal)",)


@pytest.mark.parametrize("rate", [0.0, 0.5, 1001.0, math.nan, math.inf])
def test_a_rate_out_of_range_is_refused(rate) -> None:
    with pytest.raises(StalmError, match=r"--rate .*: the sample rate must be 1 to 1000 Hz"):
        check_rate(rate)


def test_stalm_export_writes_the_trajectories_beside_the_result(monkeypatch, capsys, tmp_path):
    result = tmp_path / "p2.json"
    result.write_text(RESULT_FILE.read_text())
    assert run_cli(monkeypatch, "export", str(result), "--rate", "20") == 0
    written = json.loads(default_output(result).read_text())
    assert default_output(result).name == "p2.trajectories.json"
    assert written["rate"] == 20.0 and written["source"] == "p2.json"
    assert "18 trajectories" in capsys.readouterr().out
    check_trajectories(written, RESULT["plan"])


def test_stalm_export_refuses_a_bad_rate_before_any_work(monkeypatch, capsys, tmp_path):
    out = tmp_path / "t.json"
    code = run_cli(monkeypatch, "export", str(RESULT_FILE), "-o", str(out), "--rate", "0")
    assert code == 2 and "the sample rate must be 1 to 1000 Hz" in capsys.readouterr().err
    assert not out.exists()


def test_stalm_export_refuses_a_file_that_is_no_result(monkeypatch, capsys, tmp_path):
    bad = tmp_path / "list.json"
    bad.write_text("[1, 2]")
    assert run_cli(monkeypatch, "export", str(bad)) == 2
    assert "not a stalm result" in capsys.readouterr().err
    assert not default_output(bad).exists()


def test_a_p5_result_exports_within_the_urdf_limits(monkeypatch, tmp_path) -> None:
    """The issue's done-when, on a recorded P5 solve: the export keeps the URDF's limits."""
    out = tmp_path / "p5.trajectories.json"
    assert run_cli(monkeypatch, "export", str(P5_FILE), "-o", str(out)) == 0
    plan = json.loads(P5_FILE.read_text())["plan"]
    exported = json.loads(out.read_text())
    check_trajectories(exported, plan)
    assert exported["problem"] == "P5" and len(exported["events"]) == len(plan) == 15
    assert exported["reached_goal"]


@pytest.mark.slow
def test_a_p5_solve_exports_within_the_urdf_limits(monkeypatch, tmp_path) -> None:
    """The issue's done-when on a fresh solve: ``stalm export`` of a P5 result keeps the
    limits of the URDF."""
    result, out = tmp_path / "p5.json", tmp_path / "p5.trajectories.json"
    assert run_cli(monkeypatch, "solve", "P5", "--seed", "0", "--json", str(result), "-q") == 0
    assert run_cli(monkeypatch, "export", str(result), "-o", str(out)) == 0
    plan = json.loads(result.read_text())["plan"]
    exported = json.loads(out.read_text())
    check_trajectories(exported, plan)
    assert exported["problem"] == "P5" and len(exported["events"]) == len(plan)


def test_an_export_over_a_limit_is_never_returned(problems, monkeypatch) -> None:
    import stalm.trial.export as export

    def one_violation_double(exported, limits, tolerance=0.0):  # as if the timing overshot
        return ["trajectory 0 (pick(bottle1), base): speed 1.2 over 1"]

    monkeypatch.setattr(export, "limit_violations", one_violation_double)
    with pytest.raises(RuntimeError, match="exceeds a limit: trajectory 0"):
        export_result(problems["P2"], copy.deepcopy(RESULT), rate=5.0)


def test_stalm_export_prints_the_replays_warnings(monkeypatch, capsys, tmp_path) -> None:
    data = copy.deepcopy(RESULT)
    data["plan"] = data["plan"][:1]
    result = tmp_path / "short.json"
    result.write_text(json.dumps(data))
    assert run_cli(monkeypatch, "export", str(result), "--rate", "5") == 0
    assert "warning: the plan does not reach the goal" in capsys.readouterr().err
    assert default_output(result).exists()


def test_stalm_export_says_when_it_cannot_write(monkeypatch, capsys, tmp_path) -> None:
    import stalm.cli.export_commands as commands

    def full_disk_double(path, text):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(commands, "write_replacing", full_disk_double)
    out = tmp_path / "t.json"
    assert run_cli(monkeypatch, "export", str(RESULT_FILE), "-o", str(out), "--rate", "5") == 2
    err = capsys.readouterr().err
    assert f"--output {out}: cannot write it (No space left on device)" in " ".join(err.split())


def test_an_open_whose_waypoints_miss_its_handle_configuration_is_a_clear_error(problems) -> None:
    """A foreign record's OPEN may replay (its handle reach and its sweep are checked apart)
    with waypoints that never pass through its handle configuration: the event has no time,
    which is said in one line, not a bare ValueError."""
    from stalm.domain.params import OpenParams
    from stalm.domain.schedule import schedule_plan
    from stalm.trial.replay import replay_result_json

    report = replay_result_json(problems["P2"], RESULT)
    opening = next(a for a in report.actions if isinstance(a.params, OpenParams))
    params = opening.params
    assert isinstance(params, OpenParams)
    waypoints = tuple(w for w in params.arm_waypoints if w != params.handle_conf)
    forged = dataclasses.replace(
        opening, params=dataclasses.replace(params, arm_waypoints=waypoints)
    )
    with pytest.raises(StalmError, match="do not pass through the configuration"):
        schedule_plan([forged], panda_limits())
