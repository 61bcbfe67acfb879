"""One ``stalm experiment`` writes a results file at a time (issue 30, item 7).

A second run on the same file exits 1 before any trial, with a line naming the running one's
host and process id; a lock file left by a dead run never blocks (the OS released its lock).
The running trials are replaced by a double of ``run_experiment``: what is tested is the lock
the command holds around them.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from stalm.experiments import runner
from stalm.experiments.results_log import read_records
from stalm.experiments.runner import RunSummary
from tests.cli_runner import run_cli

ROOT = Path(__file__).resolve().parents[2]
COMMAND = ["experiment", "table2", "--problems", "P2", "--planners", "uct", "--trials", "1"]


def _stalm(*args: str) -> subprocess.CompletedProcess[str]:
    """``stalm ARGS`` in a child process running this worktree's code."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-c", "from stalm.cli.main import main; main()", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )


def _record_each(specs, log) -> RunSummary:
    """What a run of ``specs`` leaves, without running them: one finished record each."""
    for spec in specs:
        log.append(
            {
                "key": spec.key,
                "arm": spec.arm.label,
                "problem": spec.problem,
                "trial": spec.trial,
                "termination": "timeout",
                "success": False,
                "time_s": 1.0,
                "time_budget_s": spec.time_budget_s,
            }
        )
    return RunSummary(len(specs), 0, len(specs), 0, 0)


def test_a_second_run_on_the_same_results_exits_1_naming_the_first(
    monkeypatch, tmp_path: Path, capsys
) -> None:
    results = tmp_path / "table2.jsonl"
    seen: list[subprocess.CompletedProcess[str]] = []

    def run_while_another_starts(specs, log, **_: object) -> RunSummary:
        # while this run holds the file, a second `stalm experiment` on it is refused
        seen.append(_stalm(*COMMAND, "--results", str(results)))
        return _record_each(specs, log)

    monkeypatch.setattr(runner, "run_experiment", run_while_another_starts)
    assert run_cli(monkeypatch, *COMMAND, "--results", str(results)) == 0
    [second] = seen
    assert second.returncode == 1, second.stderr
    line = " ".join(second.stderr.split())
    assert f"{results} is being written by another stalm experiment" in line
    assert f"host {socket.gethostname()}, process {os.getpid()}" in line
    assert "Traceback" not in second.stderr
    assert len(read_records(results).records) == 1  # the second wrote nothing


def test_the_lock_is_released_when_the_run_ends(monkeypatch, tmp_path: Path) -> None:
    results = tmp_path / "table2.jsonl"
    calls: list[int] = []

    def no_trials(specs, log, **_: object) -> RunSummary:
        calls.append(len(specs))
        return _record_each(specs, log)

    monkeypatch.setattr(runner, "run_experiment", no_trials)
    assert run_cli(monkeypatch, *COMMAND, "--results", str(results)) == 0
    assert run_cli(monkeypatch, *COMMAND, "--results", str(results)) == 0
    assert calls == [1, 1]  # the first run let go of the file


def test_a_lock_left_by_a_dead_run_does_not_block(monkeypatch, tmp_path: Path) -> None:
    results = tmp_path / "table2.jsonl"
    # a run killed with SIGKILL leaves its lock file naming it; its lock died with it
    lock = results.with_name(results.name + ".lock")
    lock.write_text("host elsewhere, process 999999999, since 2024-01-01 00:00:00\n")
    calls: list[int] = []

    def no_trials(specs, log, **_: object) -> RunSummary:
        calls.append(len(specs))
        return _record_each(specs, log)

    monkeypatch.setattr(runner, "run_experiment", no_trials)
    assert run_cli(monkeypatch, *COMMAND, "--results", str(results)) == 0
    assert calls == [1]


def test_a_lock_that_cannot_be_made_is_one_line(monkeypatch, tmp_path: Path, capsys) -> None:
    results = tmp_path / "table2.jsonl"
    results.with_name(results.name + ".lock").mkdir()
    monkeypatch.setattr(runner, "run_experiment", pytest.fail)
    assert run_cli(monkeypatch, *COMMAND, "--results", str(results)) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"cannot lock {results}" in err
