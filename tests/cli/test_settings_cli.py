"""The settings tree on the command line: ``--show-settings``, ``--settings`` and ``--set`` in
their order, and bad keys as one error line."""

from __future__ import annotations

import pytest
import yaml

from stalm.planners.registry import RunSettings
from stalm.planners.settings_io import from_mapping
from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli


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
