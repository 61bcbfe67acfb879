"""What the problem check finds reaches the user (issue 46, item 11): ``stalm problems
--file`` says how far its check of a scene is, object by object (500 objects once took 113 s
without a word), and a solve whose goal the check found unreachable says so, up front and at
the end, with 'unreachable_goal' as its termination instead of a bare 'timeout'."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from stalm.cli import world_commands
from stalm.world.problem import Problem, shipped_problems_dir
from tests.cli_runner import run_cli


def test_problems_file_says_how_far_its_check_is(problems: dict[str, Problem]) -> None:
    heard: list[str] = []
    world_commands.check_scenes([problems["P2"]], heard.append)
    assert heard[0] == "checking P2's scene in the simulator..."
    counts = [line.rsplit(" ", 3)[1:] for line in heard[1:-1]]
    assert heard[1].startswith("checking P2: can each object be picked and put down? ")
    assert heard[-1] == "checking P2: does every object rest where the file puts it?"
    assert counts == [[str(done), "of", "4"] for done in range(5)]


def _stuck_goal(tmp_path: Path) -> Path:
    """P2 with table1's standing pose 1.55 m from the table, so nothing on it can be picked,
    bottle1 standing there, and the goal bottle1 on table2."""
    data = yaml.safe_load((shipped_problems_dir() / "p2.yaml").read_text())
    table1 = next(r for r in data["regions"] if r["name"] == "table1")
    table1["base_pose"] = [3.0, -3.55, 1.570796]
    bottle1 = next(o for o in data["objects"] if o["name"] == "bottle1")
    bottle1.update(on="table1", at=[0.0, 0.0])
    data["goal"] = [["bottle1", "on", "table2"]]
    path = tmp_path / "stuck-goal.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_solve_says_its_goal_is_unreachable_and_names_it(tmp_path, monkeypatch, capsys) -> None:
    problem = _stuck_goal(tmp_path)
    result = tmp_path / "result.json"
    args = ["solve", str(problem), "--proposer", "symbolic", "--time-budget", "3"]
    assert run_cli(monkeypatch, *args, "--json", str(result)) == 1
    captured = capsys.readouterr()
    err = " ".join(captured.err.split())
    why = (
        "goal[0] ('bottle1' on 'table2'): 'bottle1' can never be moved: no sampled pick "
        "reaches it without touching the static scene"
    )
    assert f"warning: {problem}: the goal cannot be reached: {why}; the solve runs" in err
    assert "not solved (unreachable_goal)" in captured.out
    assert f"the goal cannot be reached: {why}" in err.split("; the solve runs")[1]
    assert "timed out" not in err  # no advice to spend more time on it
    record = json.loads(result.read_text())
    assert record["termination"] == "unreachable_goal" and not record["success"]
    assert record["details"]["unreachable_goal"] == why
    assert record["details"]["run_ended_by"] in ("timeout", "no_progress", "horizon")
