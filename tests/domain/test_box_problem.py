"""The shipped problem of boxes is solved by ``stalm solve`` with its defaults, and its plan
stands up under the physics check: the boxes rest where the plan puts them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stalm.trial.replay import replay_result_json
from stalm.world.physics_check import check_physics
from stalm.world.problem import load_problem
from tests.cli_runner import run_cli


@pytest.mark.slow
def test_box1_is_solved_and_its_plan_passes_the_physics_check(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    result = tmp_path / "box1.json"
    assert run_cli(monkeypatch, "solve", "BOX1", "--seed", "0", "--json", str(result), "-q") == 0
    record = json.loads(result.read_text())
    assert record["success"] is True
    problem = load_problem("BOX1")
    replay = replay_result_json(problem, record)
    assert replay.reached_goal
    words = [str(action) for action in replay.actions]
    # the can goes onto the ledge only after the crate has left it; the crackers move first
    assert words.index("pick(crate)") < words.index("place(can, on, ledge)")
    assert words.index("pick(crackers)") < words.index("pick(cereal)")
    report = check_physics(problem, replay.states, words)
    assert report.passed, report.failure_line()
