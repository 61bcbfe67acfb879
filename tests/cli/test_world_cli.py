from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tests.cli_runner import run_cli


@pytest.fixture(scope="module")
def two_bottle_p2(tmp_path_factory: pytest.TempPathFactory, problems) -> Path:
    """P2 without bottle3 and with three of its seven regions: the salter still stands behind
    bottle2 and the closed door, and its predicates cost about 40% of P2's to compute."""
    data = yaml.safe_load(Path(problems["P2"].source).read_text())
    data["objects"] = [o for o in data["objects"] if o["name"] != "bottle3"]
    kept = {"counter1", "counter2", "table2"}
    data["regions"] = [r for r in data["regions"] if r["name"] in kept]
    path = tmp_path_factory.mktemp("problems") / "p2_two_bottles.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_problems_lists_every_shipped_problem(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "problems", "--json") == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == [
        "BOX1",
        "MESH1",
        "MOVE2",
        "MUG1",
        "P1",
        "P2",
        "P3",
        "P4",
        "P5",
        "P6",
        "TABLE1",
    ]
    assert [r["placements"] for r in rows] == [19, 18, 10, 23, 31, 23, 50, 27, 24, 27, 19]
    assert run_cli(monkeypatch, "problems") == 0
    assert "P5" in capsys.readouterr().out


def test_render_writes_a_png(monkeypatch, tmp_path: Path) -> None:
    out = tmp_path / "p5.png"
    assert run_cli(monkeypatch, "render", "P5", "-o", str(out), "--size", "64") == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_render_a_given_state(monkeypatch, tmp_path: Path, problems) -> None:
    state_file = tmp_path / "state.json"
    state_file.write_text(json.dumps(problems["P2"].initial_state.to_json()))
    out = tmp_path / "s.png"
    assert (
        run_cli(
            monkeypatch, "render", "P2", "--state", str(state_file), "-o", str(out), "--size", "64"
        )
        == 0
    )
    assert out.exists()
    state_file.write_text("{not json")
    assert run_cli(monkeypatch, "render", "P2", "--state", str(state_file), "-o", str(out)) == 2


def test_user_errors_are_one_line_and_exit_2(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "render", "P42") == 2
    err = capsys.readouterr().err
    assert "error:" in err and "unknown problem 'P42'" in err and "Traceback" not in err


def test_predicates_prompt_and_parse_reply_commands(
    monkeypatch, capsys, tmp_path: Path, two_bottle_p2: Path
) -> None:
    assert run_cli(monkeypatch, "predicates", str(two_bottle_p2), "--json") == 0
    literals = [tuple(x) for x in json.loads(capsys.readouterr().out)]
    assert ("HandAvailable", "") in literals
    assert ("PickOccludedBy", "salter", "bottle2") in literals

    assert run_cli(monkeypatch, "prompt", str(two_bottle_p2), "--no-challenges") == 0
    prompt = capsys.readouterr().out
    assert (
        "(:goal (and (AtPosition salter on table2) (AtPosition salter right_of bottle1) ) )"
        in prompt
    )
    assert "('PickOccludedBy', 'salter', 'bottle2')" in prompt
    assert "Possible Challenges" not in prompt

    reply = tmp_path / "reply.txt"
    reply.write_text("plan = [('pick', 'bottle2'), ('place', 'bottle2', 'on', 'counter9')]")
    assert run_cli(monkeypatch, "parse-reply", str(reply), "--problem", "P2") == 0
    parsed = json.loads(capsys.readouterr().out)
    assert parsed["plan"] == [["pick", "bottle2"]]
    assert parsed["errors"] and "counter9" in json.dumps(parsed["errors"])


@pytest.mark.slow
def test_the_readmes_first_solve_solves_offline_with_no_model_named(
    monkeypatch, capsys, tmp_path: Path, problems
) -> None:
    """The README's first command: with no model named, STaLM runs on the symbolic proposer,
    says so naming how to run a model, reaches the goal, and writes a JSON that replays, a GIF
    and the page of `stalm view`."""
    for variable in ("STALM_LLM", "STALM_LLM_BASE_URL"):
        monkeypatch.delenv(variable, raising=False)
    result_file, gif, page = tmp_path / "p2.json", tmp_path / "p2.gif", tmp_path / "p2.html"
    code = run_cli(
        monkeypatch,
        "solve",
        "P2",
        "--time-budget",
        "300",
        "--json",
        str(result_file),
        "--gif",
        str(gif),
        "--html",
        str(page),
    )
    captured = capsys.readouterr()
    note = " ".join(captured.err.split())
    assert "--proposer symbolic" in note and "--llm embedded" in note, captured.err
    data = json.loads(result_file.read_text())
    assert (data["planner"], data["problem"], data["success"], code) == ("stalm", "P2", True, 0)
    assert data["details"]["proposer"].startswith("symbolic") and data["counters"]["llm_calls"] == 0
    assert data["problem_hash"] == problems["P2"].content_hash
    assert "P2 with stalm (seed 0)" in captured.out
    assert gif.read_bytes()[:6] == b"GIF89a"
    html = page.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>") and "salter" in html
    assert run_cli(monkeypatch, "replay", str(result_file)) == 0
    assert "the goal is reached" in capsys.readouterr().out


def test_a_named_model_keeps_the_language_model_proposer(monkeypatch) -> None:
    from stalm.cli.solve_commands import default_proposer

    monkeypatch.delenv("STALM_LLM", raising=False)
    monkeypatch.delenv("STALM_LLM_BASE_URL", raising=False)
    assert default_proposer("stalm", None) == "symbolic"
    assert default_proposer("stalm-no-uct", "") == "symbolic"
    assert default_proposer("stalm", "embedded") == "llm"
    assert default_proposer("ep-saycan", None) == "llm"  # no symbolic proposer there
    monkeypatch.setenv("STALM_LLM", "ollama:llama3")
    assert default_proposer("stalm", None) == "llm"
    monkeypatch.delenv("STALM_LLM")
    monkeypatch.setenv("STALM_LLM_BASE_URL", "http://127.0.0.1:9/v1")
    assert default_proposer("stalm", None) == "llm"


def test_an_unknown_planner_is_a_usage_error(monkeypatch) -> None:
    assert run_cli(monkeypatch, "solve", "P2", "--planner", "nope") == 2


def test_replay_reports_a_bad_file(monkeypatch, capsys, tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"problem": "P2", "plan": [{"action": ["fly", "x"]}]}')
    assert run_cli(monkeypatch, "replay", str(bad)) == 2
    assert "not a discrete action" in capsys.readouterr().err


def test_benchmarks_run_and_print_their_tables(monkeypatch, capsys, tmp_path: Path) -> None:
    rows = tmp_path / "world.json"
    assert run_cli(monkeypatch, "bench", "world", "P2", "--attempts", "3", "--json", str(rows)) == 0
    data = json.loads(rows.read_text())
    assert data[0]["problem"] == "P2" and data[0]["pick"]["n"] >= 3
    assert run_cli(monkeypatch, "bench", "search", "P2", "--sims", "2") == 0
    out = capsys.readouterr().out
    assert "simulations/s" in out and "13-step plan" in out
    ik_rows = tmp_path / "ik.json"
    args = ["bench", "ik", "P2", "--targets", "12", "--json", str(ik_rows)]
    assert run_cli(monkeypatch, *args) == 0
    ik_row = json.loads(ik_rows.read_text())[0]
    assert ik_row["targets"] == 12 and ik_row["attempt_s"] > 0 and ik_row["reference_attempt_s"] > 0
    assert 9 <= ik_row["reached"] <= 12 and 9 <= ik_row["reference_reached"] <= 12
    assert "IK: compiled / PyBullet's" in capsys.readouterr().out


@pytest.mark.slow
def test_predicate_benchmark_checks_the_cache(
    monkeypatch, tmp_path: Path, two_bottle_p2: Path
) -> None:
    rows = tmp_path / "predicates.json"
    args = ["bench", "predicates", str(two_bottle_p2), "--json", str(rows), "--workers", "2"]
    assert run_cli(monkeypatch, *args) == 0
    row = json.loads(rows.read_text())[0]
    assert row["full_s"] > 0 and row["reference_full_s"] > 0 and row["literals"] > 10
    assert row["forked_workers"] == 2 and row["forked_full_s"] > 0 and row["forked_equal"] is True
    assert row["relevant_full_s"] > 0 and 0 < row["relevant_literals"] <= row["literals"]
    assert row["literals_equal"] is True and row["missed"] == 0  # the engines agree
    for kind in ("open", "pick", "place"):
        assert row[kind]["equal"] is True, kind  # the cached update equals a fresh computation
        assert row[kind]["update_s"] > 0 and row[kind]["reference_update_s"] > 0
