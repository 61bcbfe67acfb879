"""The shipped problem of meshes is solved by ``stalm solve`` with its defaults, the toy once
the two plates in front of it have moved, and its plan stands up under the physics check."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stalm.trial.replay import replay_result_json
from stalm.world.physics_check import check_physics
from stalm.world.problem import load_problem
from tests.cli_runner import run_cli


@pytest.mark.slow
def test_mesh1_is_solved_and_its_plan_passes_the_physics_check(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    result = tmp_path / "mesh1.json"
    assert run_cli(monkeypatch, "solve", "MESH1", "--seed", "0", "--json", str(result), "-q") == 0
    record = json.loads(result.read_text())
    assert record["success"] is True
    problem = load_problem("MESH1")
    replay = replay_result_json(problem, record)
    assert replay.reached_goal
    words = [str(action) for action in replay.actions]
    assert words.index("pick(plate_left)") < words.index("pick(toy)")
    assert words.index("pick(plate_right)") < words.index("pick(toy)")
    report = check_physics(problem, replay.states, words)
    assert report.passed, report.failure_line()
