"""Which model ``stalm rerun`` asks (issue 30, item 1): the one the user names (``--llm``,
``$STALM_LLM``) or none at all -- replies from the reply cache only. A server named only by
the record is never contacted and never sees the user's key, and the console names the model
and the server it uses."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli
from tests.llm.llm_doubles import ScriptedHTTPServerDouble, ScriptedReply, chat_completion

P2_REPLY = Path(__file__).resolve().parents[1] / "llm" / "data" / "figure08_p2_reply.txt"


@pytest.fixture
def server() -> Iterator[ScriptedHTTPServerDouble]:
    """An OpenAI-compatible server on 127.0.0.1 that records who called it, with what key."""
    double = ScriptedHTTPServerDouble()
    double.script = [ScriptedReply(body=chat_completion([P2_REPLY.read_text()] * 5))]
    double.start()
    yield double
    double.stop()


@pytest.fixture(autouse=True)
def _user_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """The user's key is set; no model is named; the reply cache is the test's own."""
    for name in ("STALM_LLM", "STALM_LLM_BASE_URL", "STALM_LLM_MODEL", "OPENAI_API_KEY"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("STALM_LLM_API_KEY", "SECRET")
    monkeypatch.setenv("STALM_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def url_record(url: str, **llm: Any) -> dict[str, Any]:
    """A record of a one-step STaLM trial on P2 (two simulations, the best-Q rule: no clock
    decides anything) whose proposer asks ``url``'s fake-model."""
    return {
        "problem": "P2",
        "planner": "stalm",
        "seed": 0,
        "plan": [],
        "settings": {
            "budget": {"horizon": 1, "time_budget_s": 120.0},
            "search": {"batch": 1, "sims": 2},
            "proposer": {"kind": "llm"},
            "execution": {"rule": "best_q"},
            "llm": {"backend": f"{url}#fake-model", "constrained": False, **llm},
        },
    }


def write(path: Path, record: dict[str, Any]) -> Path:
    path.write_text(json.dumps(record), encoding="utf-8")
    return path


def test_a_server_named_only_by_the_record_is_never_contacted(
    monkeypatch, capsys, tmp_path, server
) -> None:
    record = write(tmp_path / "rec_url.json", url_record(server.base_url))
    assert run_cli(monkeypatch, "rerun", str(record)) == 2
    assert server.paths == [] and server.authorizations == [], "nothing reached the server"
    err = capsys.readouterr().err
    assert "fake-model" in err and server.base_url in err, "the console names model and server"
    assert "not contacted" in err
    assert "--llm" in one_error_line(err), "the miss says how to ask a model"
    assert "SECRET" not in err


def test_the_model_named_with_llm_is_asked_and_named(monkeypatch, capsys, tmp_path, server) -> None:
    record = write(tmp_path / "rec.json", url_record("http://127.0.0.1:9/v1"))
    spec = f"{server.base_url}#fake-model"
    run_cli(monkeypatch, "rerun", str(record), "--llm", spec)
    assert server.authorizations and set(server.authorizations) == {"Bearer SECRET"}
    err = capsys.readouterr().err
    assert f"model 'fake-model' on {server.base_url} (--llm)" in err
    assert "127.0.0.1:9/" in err, "the record's model is named as the record's"


def test_the_model_named_in_stalm_llm_is_asked(monkeypatch, capsys, tmp_path, server) -> None:
    record = write(tmp_path / "rec.json", url_record("http://127.0.0.1:9/v1"))
    monkeypatch.setenv("STALM_LLM", f"{server.base_url}#fake-model")
    run_cli(monkeypatch, "rerun", str(record))
    assert server.paths, "the user's $STALM_LLM names the server"
    assert f"model 'fake-model' on {server.base_url} ($STALM_LLM)" in capsys.readouterr().err


def test_without_a_model_the_reply_cache_replays_the_record(
    monkeypatch, capsys, tmp_path, server
) -> None:
    record = write(tmp_path / "rec.json", url_record(server.base_url))
    first, second = tmp_path / "first.json", tmp_path / "second.json"
    spec = f"{server.base_url}#fake-model"
    run_cli(monkeypatch, "rerun", str(record), "--llm", spec, "--json", str(first))
    asked = len(server.paths)
    assert asked > 0
    capsys.readouterr()
    run_cli(monkeypatch, "rerun", str(first), "--json", str(second))
    assert len(server.paths) == asked, "the replies came from the cache"
    err = capsys.readouterr().err
    assert "from the reply cache only" in err and "fake-model" in err
    done, again = json.loads(first.read_text()), json.loads(second.read_text())
    assert again["plan"] == done["plan"] and again["termination"] == done["termination"]
    assert again["termination"] != "error"
