"""Bad numbers and arguments are one error line, never a hang or a traceback (issue 30, items
9-11): settings files get the problem files' guards, the Python API checks what the CLI
checks, and sizes, depths and non-finite values that crashed deep inside are refused at the
door."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli

ALIAS_BOMB = "".join(
    f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]\n" for i in range(1, 12)
).replace("*l0", "0")
"""About 500 bytes standing for 9**11 values once its aliases are expanded."""


@pytest.mark.parametrize(
    ("content", "named"),
    [
        (ALIAS_BOMB, "more than"),
        ("search: &s {c: *s}\n", "more than"),
        ("search:\n  c: '" + "x" * 1_100_000 + "'\n", "too long"),
        ("search: [unclosed\n", "not valid YAML"),
        ("search:\n  c: [" + "1, " * 50 + "1]\n", "search.c"),
    ],
)
def test_hostile_settings_files_are_one_error_line(
    monkeypatch, capsys, tmp_path: Path, content: str, named: str
) -> None:
    path = tmp_path / "run.yaml"
    path.write_text(content)
    started = time.monotonic()
    code = run_cli(monkeypatch, "solve", "P2", "--settings", str(path), "--show-settings")
    err = capsys.readouterr().err
    assert code == 2, err
    line = one_error_line(err)
    assert str(path) in line and named in line
    assert len(line) < 400
    assert time.monotonic() - started < 10


def test_a_device_as_settings_file(monkeypatch, capsys) -> None:
    code = run_cli(monkeypatch, "solve", "P2", "--settings", "/dev/zero", "--show-settings")
    assert code == 2
    assert "/dev/zero" in one_error_line(capsys.readouterr().err)
