"""A path inside a file someone sent (a result's or record's problem) is read with a bound and
never echoed (issue 30, item 4): only regular files, at most the problem-file size limit, and
an error quotes the file only as a short escaped excerpt. The same for ``--problems`` and
``render --state``."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.files import MAX_PROBLEM_FILE_BYTES, read_bytes
from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli

RESULT = Path(__file__).parent.parent / "planners" / "data" / "p2_result.json"
SECRET_LINES = [
    "root:$6$Xy8pQ2$secrethashsecrethashsecrethash:19000:0:99999:7:::",
    "daemon:*:19000:0:99999:7:::",
    "alice:$6$Ab3d$anothersecrethashanothersecret:19000:0:99999:7:::",
    "token: hunter2-very-secret-token",
]


def _result_naming(tmp_path: Path, problem: str) -> Path:
    data = json.loads(RESULT.read_text())
    data["problem"] = problem
    path = tmp_path / "result.json"
    path.write_text(json.dumps(data))
    return path


@pytest.fixture
def secret_file(tmp_path: Path) -> Path:
    path = tmp_path / "shadow"
    path.write_text("\n".join(SECRET_LINES) + "\n")
    return path


@pytest.mark.parametrize("command", ["replay", "view", "rerun", "export"])
def test_a_problem_path_in_a_result_is_not_echoed(
    monkeypatch, capsys, tmp_path, secret_file, command
) -> None:
    result = _result_naming(tmp_path, str(secret_file))
    if command == "rerun":  # a record needs its settings tree to get as far as the problem
        data = json.loads(result.read_text())
        data["settings"] = {}
        result.write_text(json.dumps(data))
    assert run_cli(monkeypatch, command, str(result)) == 2
    err = capsys.readouterr().err
    line = one_error_line(err)
    assert str(secret_file) in line
    for secret in ("secrethash", "anothersecret", "hunter2", "daemon", "alice"):
        assert secret not in err, err
    assert len(err) < 600


@pytest.mark.parametrize("special", ["/dev/zero", "/dev/urandom"])
def test_a_device_named_as_problem_is_refused_at_once(
    monkeypatch, capsys, tmp_path, special
) -> None:
    result = _result_naming(tmp_path, special)
    started = time.monotonic()
    assert run_cli(monkeypatch, "replay", str(result)) == 2
    assert "regular file" in one_error_line(capsys.readouterr().err)
    results = tmp_path / "r.jsonl"
    args = ("experiment", "table2", "--planners", "uct", "--trials", "1", "--results")
    assert run_cli(monkeypatch, *args, str(results), "--problems", special) == 2
    assert special in one_error_line(capsys.readouterr().err)
    png = str(tmp_path / "x.png")
    assert run_cli(monkeypatch, "render", "P2", "--state", special, "-o", png) == 2
    assert special in one_error_line(capsys.readouterr().err)
    assert time.monotonic() - started < 30


def test_a_fifo_named_as_problem_does_not_block(monkeypatch, capsys, tmp_path) -> None:
    import os

    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    result = _result_naming(tmp_path, str(fifo))
    assert run_cli(monkeypatch, "replay", str(result)) == 2
    assert "regular file" in one_error_line(capsys.readouterr().err)


def test_a_large_file_is_read_only_up_to_the_limit(tmp_path, monkeypatch) -> None:
    big = tmp_path / "big.yaml"
    with big.open("wb") as handle:
        handle.truncate(50 * MAX_PROBLEM_FILE_BYTES)  # sparse: big but cheap
    asked: list[int] = []
    real_open = __import__("os").fdopen

    def counting_fdopen(fd, mode="r", *args, **kwargs):  # type: ignore[no-untyped-def]
        handle = real_open(fd, mode, *args, **kwargs)
        read = handle.read

        def bounded(size: int = -1) -> bytes:
            asked.append(size)
            return read(size)

        handle.read = bounded
        return handle

    monkeypatch.setattr("stalm.files.os.fdopen", counting_fdopen)
    with pytest.raises(StalmError, match="too long"):
        read_bytes(big, MAX_PROBLEM_FILE_BYTES, "problem file")
    assert asked == [MAX_PROBLEM_FILE_BYTES + 1]


def test_a_yaml_error_does_not_quote_the_line(tmp_path) -> None:
    from stalm.world.problem import load_problem

    path = tmp_path / "p.yaml"
    path.write_text("name: x\nkey: secret-value: more-secret\n")
    with pytest.raises(StalmError) as error:
        load_problem(path)
    assert "secret" not in str(error.value)
    assert "line 2" in str(error.value)
