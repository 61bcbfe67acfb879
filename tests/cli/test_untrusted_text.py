"""Text from files, replies and servers reaches the terminal as text: never as Rich markup
(a crash, or bracketed text lost) and never as raw control codes (issue 16, item 4)."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest
import yaml

from stalm.cli.display import printable, shown
from stalm.world.problem import shipped_problems_dir
from tests.cli_runner import run_cli
from tests.llm.llm_doubles import ScriptedHTTPServerDouble, ScriptedReply, chat_completion

HOSTILE = "[/] [bold]loud[/bold] \x1b[2J\x1b]0;pwned\x07 \x9b31m \u202edesrever\u202c done"


def no_control_codes(text: str) -> None:
    assert "\x1b" not in text and "\x07" not in text and "\x9b" not in text
    assert "\u202e" not in text


@pytest.fixture
def server() -> Iterator[ScriptedHTTPServerDouble]:
    double = ScriptedHTTPServerDouble()
    double.start()
    yield double
    double.stop()


@pytest.fixture(autouse=True)
def _no_llm_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("STALM_LLM", "STALM_LLM_BASE_URL", "STALM_LLM_MODEL", "OPENAI_API_KEY"):
        monkeypatch.delenv(name, raising=False)


def test_the_helper_escapes_markup_and_control_codes() -> None:
    assert printable("a\x1b[31mb\tc\nd\x7f\u202e") == "a\\x1b[31mb\tc\nd\\x7f\\u202e"
    assert shown("[/]") == "\\[/]"
    from rich.console import Console

    console = Console(record=True, width=200)
    console.print(shown(HOSTILE))
    text = console.export_text()
    assert "[/] [bold]loud[/bold]" in text
    no_control_codes(text)


def test_llm_check_prints_a_hostile_reply_and_model_name_as_text(
    monkeypatch, capsys, server
) -> None:
    server.script = [ScriptedReply(body=chat_completion([HOSTILE]))]
    assert run_cli(monkeypatch, "llm", "check", "--llm", f"{server.base_url}#m[/]\x1b[1m") == 0
    out = capsys.readouterr().out
    assert "[/] [bold]loud[/bold]" in out and "m[/]" in out
    no_control_codes(out)


def test_a_server_error_message_is_printed_as_text(monkeypatch, capsys, server) -> None:
    server.script = [ScriptedReply(status=400, body={"error": {"message": HOSTILE}})]
    assert run_cli(monkeypatch, "llm", "check", "--llm", f"{server.base_url}#m") == 2
    err = capsys.readouterr().err
    assert "[/] [bold]loud[/bold]" in err
    no_control_codes(err)


def test_error_messages_keep_their_bracketed_text(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "render", "P[bold]9[/bold]") == 2
    err = capsys.readouterr().err
    assert "unknown problem 'P[bold]9[/bold]'" in err


def test_problems_with_markup_in_a_name_do_not_crash(monkeypatch, capsys, tmp_path) -> None:
    data = yaml.safe_load((shipped_problems_dir() / "p2.yaml").read_text())
    data["objects"][0]["name"] = "[/]"
    data["goal"] = [[o["name"], "on", o["on"]] for o in data["objects"]][:1]
    path = tmp_path / "odd.yaml"
    path.write_text(yaml.safe_dump(data))
    code = run_cli(monkeypatch, "problems", "--file", str(path))
    captured = capsys.readouterr()
    assert code in (0, 2)  # listed, or refused on load as a name the PDDL cannot hold
    assert "[/]" in captured.out + captured.err


def test_report_prints_labels_from_the_file_as_text(monkeypatch, capsys, tmp_path) -> None:
    record = {
        "key": "k",
        "arm": "stalm\x1b[2J[/]",
        "problem": "P1",
        "trial": 0,
        "termination": "goal",
        "success": True,
        "time_s": 1.0,
        "time_budget_s": 5.0,
    }
    results = tmp_path / "r.jsonl"
    results.write_text(json.dumps(record) + "\n" + "\x1b[31mnot json\n")
    assert run_cli(monkeypatch, "report", str(results), "--out", str(tmp_path)) == 0
    captured = capsys.readouterr()
    assert "stalm\\x1b[2J[/]" in captured.out
    no_control_codes(captured.out + captured.err)


def test_parse_reply_json_has_no_raw_control_codes(monkeypatch, capsys, tmp_path) -> None:
    reply = tmp_path / "reply.txt"
    reply.write_text(f"plan = [('pick', '{HOSTILE}')]")
    assert run_cli(monkeypatch, "parse-reply", str(reply), "--problem", "P2") == 0
    out = capsys.readouterr().out
    no_control_codes(out)
    parsed = json.loads(out)
    assert parsed["steps"][0]["items"][1] == HOSTILE  # the JSON still holds the exact text
