"""The settings tree on the command line: ``--show-settings``, ``--settings`` and ``--set`` in
their order, bad keys as one error line, the tree in every result record, and ``stalm
rerun`` giving the recorded plan again from a record alone."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from stalm.settings.io import from_mapping
from stalm.settings.tree import RunSettings
from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli

DATA = Path(__file__).resolve().parents[1] / "planners" / "data"

SHORT_UCT = [
    "--planner",
    "uct",
    "--sims",
    "3",
    "--seed",
    "2",
    "--set",
    "budget.horizon=1",
    "--set",
    "execution.rule=best_q",
]
"""A uct trial of one real step whose outcome does not depend on the clock ('best_q')."""


@pytest.fixture(autouse=True)
def _no_llm_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("STALM_LLM", "STALM_LLM_BASE_URL"):
        monkeypatch.delenv(name, raising=False)


def _shown(capsys: pytest.CaptureFixture[str]) -> RunSettings:
    out = capsys.readouterr().out
    assert "plan (" not in out, "nothing is solved"
    return from_mapping(yaml.safe_load(out), "--show-settings")


def test_show_settings_prints_the_resolved_tree_and_solves_nothing(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "solve", "P3", "--planner", "uct", "--show-settings") == 0
    shown = _shown(capsys)
    assert shown.search.sims == 35 and shown.budget.time_budget_s == 600.0
    assert shown.budget.horizon == 20 and shown.execution.backtracks == 0
    assert run_cli(monkeypatch, "solve", "P2", "--show-settings") == 0
    stalm = _shown(capsys)
    assert stalm.proposer.kind == "symbolic", "no model named: the symbolic proposer"
    assert (stalm.search.sims, stalm.execution.feedback, stalm.execution.backtracks) == (
        30,
        True,
        6,
    )


def test_a_file_then_the_flags_then_set_build_the_tree(monkeypatch, capsys, tmp_path) -> None:
    run = tmp_path / "run.yaml"
    run.write_text(
        "search: {c: 10, sims: 2, batch: 2}\nproposer: {kind: llm}\n"
        "llm: {backend: 'http://127.0.0.1:9/v1#m'}\nrewards: {goal: 50}\n"
    )
    args = ["solve", "P2", "--settings", str(run), "--sims", "4", "--batch", "3"]
    assert run_cli(monkeypatch, *args, "--set", "search.batch=6", "--show-settings") == 0
    shown = _shown(capsys)
    assert shown.search.c == 10.0 and shown.rewards.goal == 50.0, "from the file"
    assert shown.search.sims == 4, "a flag overrides the file"
    assert shown.search.batch == 6, "--set overrides a flag"
    assert shown.proposer.kind == "llm", "the file's proposer, not the symbolic default"
    assert shown.llm.constrained is False, "a server: unconstrained"


def test_the_shown_settings_are_a_settings_file(monkeypatch, capsys, tmp_path) -> None:
    assert run_cli(monkeypatch, "solve", "P1", "--set", "search.gamma=0.9", "--show-settings") == 0
    saved = tmp_path / "saved.yaml"
    saved.write_text(capsys.readouterr().out)
    assert run_cli(monkeypatch, "solve", "P1", "--settings", str(saved), "--show-settings") == 0
    assert _shown(capsys).search.gamma == 0.9


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--set", "search.cc=1"], "unknown setting 'search.cc' (valid: search.sims"),
        (["--set", "execution.rule=random"], "execution.rule must be one of progress, best_q"),
        (["--set", "budget.horizon=zero"], "budget.horizon must be an integer or null"),
    ],
)
def test_a_bad_setting_is_one_error_line(monkeypatch, capsys, args, named) -> None:
    assert run_cli(monkeypatch, "solve", "P2", "--planner", "uct", *args) == 2
    assert named in one_error_line(capsys.readouterr().err)


def test_a_settings_file_that_is_not_a_mapping_is_named(monkeypatch, capsys, tmp_path) -> None:
    run = tmp_path / "run.yaml"
    run.write_text("- search.c: 1\n")
    assert run_cli(monkeypatch, "solve", "P2", "--settings", str(run), "--show-settings") == 2
    assert "run.yaml: settings must be a mapping" in one_error_line(capsys.readouterr().err)


def test_a_solve_record_keeps_the_tree_and_reruns_to_the_same_plan(
    monkeypatch, capsys, tmp_path
) -> None:
    first, second = tmp_path / "first.json", tmp_path / "second.json"
    run_cli(monkeypatch, "solve", "P2", *SHORT_UCT, "--json", str(first))
    record = json.loads(first.read_text())
    settings = from_mapping(record["settings"], "record")
    assert settings.search.sims == 3 and settings.budget.horizon == 1
    assert settings.execution.rule == "best_q" and settings.budget.time_budget_s == 300.0
    assert len(record["plan"]) == 1, "one real step (budget.horizon=1)"
    capsys.readouterr()
    assert run_cli(monkeypatch, "rerun", str(first), "--json", str(second)) == 0
    assert "the plan is the record's (1 actions)" in capsys.readouterr().out
    again = json.loads(second.read_text())
    assert again["plan"] == record["plan"] and again["seed"] == 2
    assert again["settings"] == record["settings"]
    # another machine's last bits: still the record's plan, within the tolerance
    waypoints = record["plan"][0]["arm_waypoints"]
    waypoints[2][1] += 1e-9
    first.write_text(json.dumps(record))
    assert run_cli(monkeypatch, "rerun", str(first)) == 0
    assert "(1 actions, continuous values within 2e-06)" in capsys.readouterr().out
    # beyond it: a different plan
    waypoints[2][1] += 1e-4
    first.write_text(json.dumps(record))
    assert run_cli(monkeypatch, "rerun", str(first)) == 1
    assert "differs from the record's from action 1" in capsys.readouterr().out
    # a record whose plan is not what the run gives: exit 1, saying from where
    record["plan"][0]["discrete"] = ["open", "nowhere"]
    first.write_text(json.dumps(record))
    assert run_cli(monkeypatch, "rerun", str(first)) == 1
    assert "differs from the record's from action 1" in capsys.readouterr().out


def test_an_experiment_record_reruns_to_the_same_plan(monkeypatch, capsys, tmp_path) -> None:
    results = tmp_path / "t.jsonl"
    args = ["experiment", "table2", "--problems", "P2", "--planners", "uct", "--trials", "1"]
    short = ["--sims", "3", "--set", "budget.horizon=1", "--set", "execution.rule=best_q"]
    assert run_cli(monkeypatch, *args, *short, "--results", str(results)) == 0
    [record] = [json.loads(line) for line in results.read_text().splitlines()]
    assert record["settings"]["budget"] == {"time_budget_s": 300.0, "horizon": 1}
    assert record["config"]["settings"] == {"budget.horizon": 1}, "a non-default tree: own key"
    capsys.readouterr()
    assert run_cli(monkeypatch, "rerun", str(results), "--key", record["key"][:6]) == 0
    assert "the plan is the record's" in capsys.readouterr().out


def test_a_record_without_settings_is_still_replayed_but_cannot_be_rerun(
    monkeypatch, capsys
) -> None:
    old = DATA / "p2_result.json"  # written before records kept their settings
    assert "settings" not in json.loads(old.read_text())
    assert run_cli(monkeypatch, "replay", str(old)) == 0
    capsys.readouterr()
    assert run_cli(monkeypatch, "rerun", str(old)) == 2
    assert "has no settings tree" in one_error_line(capsys.readouterr().err)


def test_rerun_refuses_a_record_of_another_problem(monkeypatch, capsys, tmp_path) -> None:
    record = {
        "problem": "P2",
        "planner": "uct",
        "seed": 0,
        "problem_hash": "0" * 16,
        "settings": {},
        "plan": [],
    }
    path = tmp_path / "r.json"
    path.write_text(json.dumps(record))
    assert run_cli(monkeypatch, "rerun", str(path)) == 2
    assert "pass the problem file it was solved on with --problem" in one_error_line(
        capsys.readouterr().err
    )
    lines = tmp_path / "r.jsonl"
    lines.write_text(
        json.dumps({**record, "key": "aa"}) + "\n" + json.dumps({**record, "key": "ab"})
    )
    assert run_cli(monkeypatch, "rerun", str(lines), "--key", "a") == 2
    assert "2 records; choose one with --key" in one_error_line(capsys.readouterr().err)


def test_old_results_without_settings_still_make_a_report(monkeypatch, capsys, tmp_path) -> None:
    old = Path(__file__).resolve().parents[2] / "docs" / "results" / "issue13" / "before.jsonl"
    records = [json.loads(line) for line in old.read_text().splitlines()]
    assert records and all("settings" not in r for r in records)
    assert run_cli(monkeypatch, "report", str(old), "--out", str(tmp_path)) == 0
    assert "| stalm-symbolic | Success rate |" in (tmp_path / "before.md").read_text()
