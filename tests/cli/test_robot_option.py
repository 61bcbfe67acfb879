"""``--robot`` on ``stalm solve``, ``stalm experiment`` and ``stalm bench predicates``: the
problem planned for another robot, recorded so that a replay reopens it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stalm.experiments.suites import build_plan, trial_specs
from stalm.experiments.trials import for_robot
from stalm.settings.tree import RunSettings
from stalm.world.problem import load_problem
from tests.cli_runner import run_cli


def test_solve_with_another_robot_solves_and_replays(monkeypatch, tmp_path: Path) -> None:
    result = tmp_path / "p2-xarm6.json"
    code = run_cli(
        monkeypatch, "solve", "P2", "--robot", "xarm6", "--seed", "0", "-q", "--json", str(result)
    )
    assert code == 0
    record = json.loads(result.read_text())
    assert record["success"] is True
    assert record["problem_spec"]["robot"]["file"] == "xarm6"
    assert record["problem_hash"] == load_problem("P2").with_robot("xarm6").content_hash
    assert all(len(step["arm_waypoints"][0]) == 7 for step in record["plan"])  # lift + 6
    assert run_cli(monkeypatch, "replay", str(result)) == 0


def test_solve_names_a_robot_it_cannot_plan_for(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "solve", "P2", "--robot", "iiwa") == 2
    assert "'iiwa' has no gripper" in capsys.readouterr().err


def test_an_experiments_trials_name_their_robot() -> None:
    plan = build_plan(
        "table2", planners=("stalm-symbolic",), problems=("P1",), trials=2, base=RunSettings()
    )
    specs = trial_specs(plan)
    moved = [for_robot(spec, "xarm6") for spec in specs]
    for spec, other in zip(specs, moved, strict=True):
        assert other.key != spec.key and other.seed == spec.seed
        assert ("robot", "xarm6") in other.fields
        assert "file: xarm6" in other.problem_yaml
    with pytest.raises(Exception, match="has no gripper"):
        for_robot(specs[0], "iiwa")


@pytest.mark.slow
def test_bench_predicates_for_another_robot_gives_the_references_literals(
    monkeypatch, capsys, tmp_path: Path
) -> None:
    rows = tmp_path / "rows.json"
    code = run_cli(
        monkeypatch, "bench", "predicates", "P1", "--robot", "xarm6", "--json", str(rows)
    )
    assert code == 0
    (row,) = json.loads(rows.read_text())
    assert row["literals_equal"] is True and row["missed"] == 0


def test_export_times_another_robots_plan_under_its_own_limits(monkeypatch, tmp_path) -> None:
    from stalm.trial.export import limit_violations
    from stalm.world.robot_limits import limits_of
    from stalm.world.robot_loader import robot_named

    result, exported = tmp_path / "p2-xarm6.json", tmp_path / "p2-xarm6-export.json"
    assert run_cli(monkeypatch, "solve", "P2", "--robot", "xarm6", "-q", "--json", str(result)) == 0
    assert run_cli(monkeypatch, "export", str(result), "-o", str(exported)) == 0
    data = json.loads(exported.read_text())
    xarm = robot_named("xarm6")
    limits = limits_of(xarm)
    assert data["limits"]["arm"]["joint_names"] == ["lift", *(f"joint{i}" for i in range(1, 7))]
    assert data["limits"]["arm"]["velocity"] == [0.1, *xarm.velocity_limits]
    assert data["limits"]["arm"]["acceleration"] == [0.5, *xarm.acceleration_limits]
    # grasps are in the tool link moved by the tool offset, both stated
    assert data["robot"]["grasp_frame"] == "xarm_gripper_base_link"
    assert data["robot"]["tool_offset"] == {"xyz": [0.0, 0.0, 0.155], "rpy": [0.0, 0.0, 0.0]}
    assert data["robot"]["urdf"] == "pybullet_data:xarm/xarm6_with_gripper.urdf"
    assert limit_violations(data, limits) == []
    assert run_cli(monkeypatch, "view", str(result), "-o", str(tmp_path / "page.html")) == 0
