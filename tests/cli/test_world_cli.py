from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from stalm.cli.main import main


def run_cli(monkeypatch: pytest.MonkeyPatch, *args: str) -> int:
    monkeypatch.setattr(sys, "argv", ["stalm", *args])
    try:
        main()
    except SystemExit as done:
        return int(done.code or 0)
    return 0


def test_problems_lists_all_six(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "problems", "--json") == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == ["P1", "P2", "P3", "P4", "P5", "P6"]
    assert [r["placements"] for r in rows] == [31, 23, 50, 27, 24, 27]
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


def test_predicates_prompt_and_parse_reply_commands(monkeypatch, capsys, tmp_path: Path) -> None:
    assert run_cli(monkeypatch, "predicates", "P2", "--json") == 0
    literals = [tuple(x) for x in json.loads(capsys.readouterr().out)]
    assert ("HandAvailable", "") in literals
    assert ("PickOccludedBy", "salter", "bottle2") in literals

    assert run_cli(monkeypatch, "prompt", "P2", "--no-challenges") == 0
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
