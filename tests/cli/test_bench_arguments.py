"""``stalm bench`` arguments are checked before the run: one error line naming the option, never
a traceback from deep inside (an IndexError, numpy's seed error) or an empty table, and
``--json`` is checked (and its folder made) before the run, not after."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli


@pytest.fixture
def no_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """Test doubles for the benchmarks' runs: any call fails the test, so each refusal is
    shown to come before the work."""

    def run_not_expected(*args: object, **kwargs: object) -> None:
        raise AssertionError("the benchmark ran although its arguments were refused")

    for module in ("bench_world", "bench_ik", "bench_predicates", "bench_search"):
        monkeypatch.setattr(f"stalm.experiments.{module}.run", run_not_expected)


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["ik", "P1", "--targets", "0"], "--targets must be at least 1, got 0"),
        (["world", "P1", "--attempts", "0"], "--attempts must be at least 1, got 0"),
        (["search", "P1", "--sims", "0"], "--sims must be at least 1, got 0"),
        (["world", "P1", "--seed", "-1"], "--seed must be a non-negative integer, got -1"),
        (["ik", "P1", "--seed", "-1"], "--seed must be a non-negative integer, got -1"),
        (["predicates", "P1", "--seed", "-1"], "--seed must be a non-negative integer, got -1"),
        (["search", "P1", "--seed", "-1"], "--seed must be a non-negative integer, got -1"),
    ],
)
def test_bad_numbers_are_one_line_before_the_run(
    monkeypatch, capsys, no_run, args: list[str], named: str
) -> None:
    assert run_cli(monkeypatch, "bench", *args) == 2
    assert named in one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize("command", ["world", "ik", "predicates"])
def test_json_naming_a_folder_is_refused_before_the_run(
    monkeypatch, capsys, tmp_path: Path, no_run, command: str
) -> None:
    assert run_cli(monkeypatch, "bench", command, "P1", "--json", str(tmp_path)) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "--json" in line and "is a folder" in line


def test_json_into_a_missing_folder_is_made(monkeypatch, tmp_path: Path) -> None:
    out = tmp_path / "new" / "deeper" / "ik.json"
    args = ["bench", "ik", "P1", "--targets", "1", "--json", str(out)]
    assert run_cli(monkeypatch, *args) == 0
    (row,) = json.loads(out.read_text())
    assert row["problem"] == "P1" and row["targets"] == 1
