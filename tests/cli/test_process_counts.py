"""``--set predicates.workers``, ``stalm bench predicates --workers`` and ``stalm experiment
--workers`` refuse more processes than the cores this process may use (its affinity mask),
and fewer than one, with one message, the same words for 0 and -1 (issue 46, item 6): 1000
predicate workers once forked 999 children on two cores."""

from __future__ import annotations

import os
import re

import pytest

from tests.cli_runner import run_cli

TOO_MANY = 1000


def _error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


def _shape(line: str, name: str, value: int) -> str:
    """The message with the option's name and its value taken out: what every command must
    share."""
    return line.replace(name, "NAME").replace(f"got {value}", "got VALUE")


@pytest.mark.parametrize("value", [0, -1, TOO_MANY])
def test_three_commands_refuse_a_count_with_one_message(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path, value: int
) -> None:
    commands = {
        f"--set predicates.workers={value}: setting predicates.workers": (
            "solve",
            "P1",
            "--time-budget",
            "5",
            "--set",
            f"predicates.workers={value}",
        ),
        "--workers": ("bench", "predicates", "P1", "--workers", str(value)),
    }
    shapes = set()
    for name, args in commands.items():
        assert run_cli(monkeypatch, *args) == 2
        shapes.add(_shape(_error_line(capsys), name, value))
    results = tmp_path / "r.jsonl"
    args = ("experiment", "table2", "--problems", "P1", "--planners", "stalm-symbolic")
    assert run_cli(monkeypatch, *args, "--results", str(results), "--workers", str(value)) == 2
    shapes.add(_shape(_error_line(capsys), "--workers", value))
    assert not results.exists()  # refused before any trial
    assert len(shapes) == 1, shapes
    (shape,) = shapes
    assert re.fullmatch(
        r"error: NAME must be a whole number of processes "
        rf"from 1 to {len(os.sched_getaffinity(0))} \(the cores this process may use\), got VALUE",
        shape,
    ), shape
