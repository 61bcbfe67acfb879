"""Plans stalm made still replay as they did: the checks that refuse forged plans (bounds,
continuity of the motions, the held object swept) refuse none of the records committed under
docs/results (issue 46). A few records of several planners and problems, read whole."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from stalm.trial.replay import replay_result_json
from stalm.world.problem_record import record_problem
from tests.cli_runner import run_cli

RESULTS = Path(__file__).parents[2] / "docs" / "results"
REACHING = [
    ("p2/pddlstream-adaptive-P2-s2.json", 0),
    ("p2/uct-hcount-P2-s0.json", 0),
    ("figure5.jsonl", 0),  # STaLM on P1
    ("figure5.jsonl", 5),  # STaLM on P3
    ("figure5.jsonl", 7),  # STaLM on P4
    ("issue26/baselines-paper.jsonl", 1),  # UCT-Hcount on P1, 17 actions
    ("issue13/after.jsonl", 16),  # STaLM on P5, before records carried the problem's hash
]


def _record(name: str, line: int) -> dict[str, Any]:
    text = (RESULTS / name).read_text()
    record = json.loads(text.splitlines()[line] if name.endswith(".jsonl") else text)
    assert isinstance(record, dict)
    return record


@pytest.mark.parametrize(("name", "line"), REACHING, ids=[f"{n}:{i}" for n, i in REACHING])
def test_a_committed_record_replays_to_the_goal(name: str, line: int) -> None:
    record = _record(name, line)
    assert record["success"] is True
    problem = record_problem(record, name, None, RESULTS)
    report = replay_result_json(problem, record)
    assert report.reached_goal, report.reason
    assert report.steps_executed == len(record["plan"]) > 0


def test_a_committed_timeout_replays_every_step(problems) -> None:
    """A run the clock stopped: every executed step replays, and the plan ends short."""
    record = _record("p2/ep-saycan-P2-s0.json", 0)
    report = replay_result_json(problems["P2"], record)
    assert not report.reached_goal and report.failed_step is None
    assert report.steps_executed == len(record["plan"]) == 11


def test_stalm_replay_confirms_a_committed_result(monkeypatch, capsys) -> None:
    path = RESULTS / "p2" / "pddlstream-adaptive-P2-s2.json"
    assert run_cli(monkeypatch, "replay", str(path)) == 0
    assert "replayed 9 actions: the goal is reached" in capsys.readouterr().out
