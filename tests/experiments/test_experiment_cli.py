"""The smoke configuration end to end: ``stalm experiment`` then ``stalm report``; a run killed
mid-way and resumed; the same trials on a real local Ray instance.

Trials are real (PyBullet, the planners, Fast Downward) with budgets of a few seconds, so
success is not asserted; that every trial has one well-formed record, is.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from stalm.cli.main import main
from stalm.experiments.results_log import ResultsLog, read_records
from stalm.experiments.runner import run_experiment
from stalm.experiments.suites import build_plan, trial_specs

# One trial per cell: several trials of one cell are the killed-run and Ray tests' (and the
# report's aggregation is test_report.py's); each STaLM trial computes predicates for 8-13 s.
SMOKE = ["--problems", "P1,P2", "--planners", "uct,stalm-symbolic", "--trials", "1"]


def run_cli(monkeypatch: pytest.MonkeyPatch, *args: str) -> int:
    monkeypatch.setattr(sys, "argv", ["stalm", *args])
    try:
        main()
    except SystemExit as done:
        return int(done.code or 0)
    return 0


def _check_records(records: tuple[dict, ...], count: int) -> None:
    assert len(records) == count
    assert len({r["key"] for r in records}) == count
    for record in records:
        assert record["termination"] in ("goal", "timeout", "horizon", "no_progress")
        assert record["success"] == (record["termination"] == "goal")
        assert record["time_s"] > 0
        assert set(record["times"]) >= {"predicates", "proposer", "tree_search", "total"}
        assert record["versions"]["stalm"]


@pytest.mark.slow
def test_smoke_experiment_and_its_report(monkeypatch, tmp_path: Path, capsys) -> None:
    results = tmp_path / "smoke.jsonl"
    args = ["experiment", "table2", *SMOKE, "--time-budget", "3", "--results", str(results)]
    assert run_cli(monkeypatch, *args, "--workers", "2") == 0
    records = read_records(results).records
    _check_records(records, 4)
    assert {(r["arm"], r["problem"]) for r in records} == {
        (arm, problem) for arm in ("uct", "stalm-symbolic") for problem in ("P1", "P2")
    }
    # the same command again: everything is done, nothing runs
    capsys.readouterr()
    assert run_cli(monkeypatch, *args) == 0
    assert "ran 0 trials" in capsys.readouterr().err
    assert len(read_records(results).records) == 4

    out_dir = tmp_path / "report"
    assert run_cli(monkeypatch, "report", str(results), "--out", str(out_dir), "--paper") == 0
    markdown = (out_dir / "smoke.md").read_text()
    assert "| uct | Success rate |" in markdown
    assert "| stalm-symbolic | Success rate |" in markdown
    rows = list(csv.DictReader((out_dir / "smoke.csv").open()))
    assert sorted((r["planner"], r["problem"], r["trials"]) for r in rows) == [
        ("stalm-symbolic", "P1", "1"),
        ("stalm-symbolic", "P2", "1"),
        ("uct", "P1", "1"),
        ("uct", "P2", "1"),
    ]
    assert (out_dir / "smoke-success.png").exists()


class PlannerDoubleThatRaises:
    """A planner whose every trial hits a bug (tests only)."""

    name = "uct"

    def solve(self, problem: object, seed: int, time_budget_s: float | None = None) -> None:
        raise RuntimeError("test double: a bug in the planner")


def test_a_trial_that_raises_is_kept_as_an_error_and_the_run_exits_1(
    monkeypatch, tmp_path: Path, capsys
) -> None:
    from stalm.experiments import trials

    monkeypatch.setattr(trials, "build_planner", lambda name, config: PlannerDoubleThatRaises())
    results = tmp_path / "errors.jsonl"
    args = ["experiment", "table2", "--problems", "P2", "--planners", "uct", "--trials", "1"]
    assert run_cli(monkeypatch, *args, "--time-budget", "1", "--results", str(results)) == 1
    [record] = read_records(results).records
    assert record["termination"] == "error" and record["success"] is False
    assert record["error"] == "RuntimeError: test double: a bug in the planner"
    assert "RuntimeError" in record["traceback"]
    err = " ".join(capsys.readouterr().err.split())
    assert "ran 1 trials (0 solved, 1 errors)" in err
    assert "1 trials ended in an error (a re-run retries them)" in err
    assert "the first: uct P2: RuntimeError: test double: a bug in the planner" in err


def test_report_of_a_missing_file_is_a_clear_error(monkeypatch, tmp_path: Path, capsys) -> None:
    assert run_cli(monkeypatch, "report", str(tmp_path / "none.jsonl")) == 2
    assert "no results file" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--rates", "0,1"], "--rates goes with the noisy proposer"),
        (["--proposer", "noisy", "--rates", "0,lots"], "--rates must be comma-separated"),
        (["--proposer", "noisy", "--rates", "0,2"], "an error rate must be in [0, 1], got 2.0"),
        (["--proposer", "gpt"], "proposer.kind must be one of llm, symbolic, noisy"),
    ],
)
def test_bad_noisy_choices_are_one_line_before_any_trial(
    monkeypatch, tmp_path: Path, capsys, args: list[str], message: str
) -> None:
    results = tmp_path / "never.jsonl"
    command = ["experiment", "table3", "--trials", "1", "--results", str(results), *args]
    assert run_cli(monkeypatch, *command) == 2
    assert message in " ".join(capsys.readouterr().err.split())
    assert not results.exists()


@pytest.mark.slow
def test_table3_on_the_noisy_proposer_and_its_curve(monkeypatch, tmp_path: Path) -> None:
    """Two rates of STaLM w/o UCT and UCT once on P2, one short trial each: the rows carry
    their rate and every plan's injected kind; the report draws the curve."""
    results = tmp_path / "table3-noisy.jsonl"
    args = ["experiment", "table3", "--proposer", "noisy", "--rates", "0,1", "--problems", "P2"]
    args += ["--planners", "stalm-no-uct,uct", "--trials", "1", "--time-budget", "20"]
    assert run_cli(monkeypatch, *args, "--results", str(results)) == 0
    records = {r["arm"]: r for r in read_records(results).records}
    assert set(records) == {"stalm-no-uct [noisy 0]", "stalm-no-uct [noisy 1]", "uct"}
    for rate in (0, 1):
        record = records[f"stalm-no-uct [noisy {rate}]"]
        assert record["settings"]["proposer"]["noise"]["rate"] == rate
        noise = record["details"]["noise"]
        assert noise["rate"] == rate and noise["plans"], record["termination"]
        injected = {plan["injected"] for plan in noise["plans"]}
        assert injected == {"clean"} if rate == 0 else "clean" not in injected
        assert record["details"]["proposer"].startswith("noisy:")
        assert record["counters"]["llm_calls"] == 0
    assert "noise" not in records["uct"]["details"]
    assert (tmp_path / "table3-noisy-noise.png").exists()
    markdown = (tmp_path / "table3-noisy.md").read_text()
    assert "| stalm-no-uct | 1 |" in markdown and "injected \\ classified" in markdown


@pytest.mark.slow
def test_a_killed_run_loses_no_finished_trial_and_resumes(tmp_path: Path) -> None:
    results = tmp_path / "killed.jsonl"
    command = [
        sys.executable,
        "-c",
        "from stalm.cli.main import main; main()",
        "experiment",
        "table2",
        "--problems",
        "P2",
        "--planners",
        "uct",
        "--trials",
        "6",
        "--time-budget",
        "2",
        "--results",
        str(results),
    ]
    temp = tmp_path / "tmp"  # a trial killed mid-run cannot remove its folder: keep it here
    temp.mkdir()
    env = {**os.environ, "TMPDIR": str(temp)}
    process = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        env=env,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if results.exists() and results.read_text().count("\n") >= 2:
            break
        time.sleep(0.2)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    before = results.read_text()
    killed = read_records(results)
    assert 2 <= len(killed.records) < 6
    assert not killed.problems and not killed.skipped_partial_line

    done = subprocess.run(
        command, capture_output=True, text=True, timeout=300, check=False, env=env
    )
    assert done.returncode == 0, done.stderr
    after = read_records(results)
    _check_records(after.records, 6)
    assert results.read_text().startswith(before)  # finished lines kept as they were
    assert f"ran {6 - len(killed.records)} trials" in done.stderr


@pytest.mark.slow
def test_trials_on_a_local_ray_instance(tmp_path: Path) -> None:
    ray = pytest.importorskip("ray")
    plan = build_plan("table2", planners=("uct",), problems=("P2",), trials=2, time_budget_s=2.0)
    log = ResultsLog(tmp_path / "ray.jsonl")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        summary = run_experiment(trial_specs(plan), log, ray_address="auto")
    finally:
        ray.shutdown()
    assert (summary.ran, summary.skipped) == (2, 0)
    records = log.load().records
    _check_records(records, 2)
    assert {r["trial"] for r in records} == {0, 1}
    assert all(r["host"] for r in records)
    json.dumps(records)  # plain data all the way
