"""A result of one's own problem file reopens anywhere: the record carries the validated
problem it was solved on, so ``stalm replay``, ``view`` and ``rerun`` need no file; the
embedded problem is untrusted input; ``--problem FILE`` is checked against the record's hash;
an older record is found by name and, failing that, the error says ``--problem FILE``
(issue 42, item 2)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest

from stalm.world.problem import load_problem, shipped_problems_dir
from stalm.world.problem_record import PROBLEM_SPEC_FIELD, problem_fields
from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli

MINE = (
    (shipped_problems_dir() / "p2.yaml")
    .read_text(encoding="utf-8")
    .replace("name: P2", "name: Mine")
)
"""P2's scene and goal as a user's own problem, named Mine."""


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``stalm solve myprob/mine.yaml --json mine.json``, then the problem file deleted."""
    folder = tmp_path_factory.mktemp("reopen")
    (folder / "myprob").mkdir()
    (folder / "myprob" / "mine.yaml").write_text(MINE, encoding="utf-8")
    with pytest.MonkeyPatch.context() as monkeypatch:
        for name in ("STALM_LLM", "STALM_LLM_BASE_URL", "STALM_LLM_MODEL"):
            monkeypatch.delenv(name, raising=False)
        monkeypatch.chdir(folder)
        assert run_cli(monkeypatch, "solve", "myprob/mine.yaml", "--json", "mine.json") == 0
    shutil.rmtree(folder / "myprob")
    return folder / "mine.json"


@pytest.fixture
def elsewhere(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    for name in ("STALM_LLM", "STALM_LLM_BASE_URL", "STALM_LLM_MODEL", "STALM_PROBLEMS_DIR"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _changed(record: Path, folder: Path, change: Any) -> Path:
    data = json.loads(record.read_text(encoding="utf-8"))
    change(data)
    path = folder / "changed.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


def test_replay_view_and_rerun_reopen_a_record_whose_problem_file_is_gone(
    record: Path, elsewhere: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    assert run_cli(monkeypatch, "replay", str(record)) == 0
    assert "the goal is reached" in capsys.readouterr().out
    page = elsewhere / "mine.html"
    assert run_cli(monkeypatch, "view", str(record), "-o", str(page)) == 0
    assert page.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    capsys.readouterr()
    assert run_cli(monkeypatch, "rerun", str(record)) == 0
    assert "the plan is the record's" in capsys.readouterr().out
    trajectories = elsewhere / "mine.trajectories.json"
    assert run_cli(monkeypatch, "export", str(record), "-o", str(trajectories)) == 0
    assert json.loads(trajectories.read_text(encoding="utf-8"))["problem"] == "Mine"


def test_the_record_carries_the_validated_problem_serialised_deterministically(
    record: Path, tmp_path: Path
) -> None:
    data = json.loads(record.read_text(encoding="utf-8"))
    (tmp_path / "mine.yaml").write_text(MINE, encoding="utf-8")
    mine = load_problem(tmp_path / "mine.yaml")
    assert data["problem"] == "Mine"
    assert data["problem_hash"] == mine.content_hash
    assert data[PROBLEM_SPEC_FIELD] == mine.spec.model_dump(mode="json")
    again = load_problem(tmp_path / "mine.yaml")
    assert json.dumps(problem_fields(mine)) == json.dumps(problem_fields(again))


@pytest.mark.parametrize("command", ["replay", "view", "rerun", "export"])
def test_an_invalid_embedded_problem_is_refused_naming_the_record_and_field(
    record: Path, elsewhere: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any, command: str
) -> None:
    def negative_radius(data: dict[str, Any]) -> None:
        data[PROBLEM_SPEC_FIELD]["objects"][0]["radius"] = -1.0

    path = _changed(record, elsewhere, negative_radius)
    assert run_cli(monkeypatch, command, str(path)) == 2
    line = one_error_line(capsys.readouterr().err)
    assert f"changed.json: {PROBLEM_SPEC_FIELD}: objects[0].radius" in line


def test_an_embedded_problem_changed_after_the_solve_is_refused(
    record: Path, elsewhere: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    def moved_robot(data: dict[str, Any]) -> None:
        data[PROBLEM_SPEC_FIELD]["robot"]["base"][0] = 0.25  # still a valid problem

    path = _changed(record, elsewhere, moved_robot)
    assert run_cli(monkeypatch, "replay", str(path)) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "not the one the record's problem_hash names" in line
    assert "changed after it was written" in line and "--problem FILE" in line

    def huge(data: dict[str, Any]) -> None:
        data[PROBLEM_SPEC_FIELD]["description"] = "x" * 1_100_000

    assert run_cli(monkeypatch, "view", str(_changed(record, elsewhere, huge))) == 2
    assert "too long for a problem" in one_error_line(capsys.readouterr().err)


def test_problem_option_overrides_and_is_checked_against_the_hash(
    record: Path, elsewhere: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    same = elsewhere / "same.yaml"
    same.write_text(MINE, encoding="utf-8")
    assert run_cli(monkeypatch, "replay", str(record), "--problem", str(same)) == 0
    capsys.readouterr()
    other = elsewhere / "other.yaml"
    other.write_text(MINE.replace("horizon: 20", "horizon: 21"), encoding="utf-8")
    for command in ("replay", "view", "rerun", "export"):
        assert run_cli(monkeypatch, command, str(record), "--problem", str(other)) == 2
        line = one_error_line(capsys.readouterr().err)
        assert f"--problem {other}: not the problem" in line
        assert load_problem(other).content_hash in line and "problem hash" in line


def test_an_older_record_loads_by_name_and_suggests_the_problem_option(
    record: Path, elsewhere: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    path = _changed(record, elsewhere, lambda data: data.pop(PROBLEM_SPEC_FIELD))
    for command in ("replay", "view", "rerun"):
        assert run_cli(monkeypatch, command, str(path)) == 2
        line = one_error_line(capsys.readouterr().err)
        assert "unknown problem 'Mine'" in line and "--problem FILE" in line
    (elsewhere / "mine.yaml").write_text(MINE, encoding="utf-8")
    assert run_cli(monkeypatch, "replay", str(path), "--problem", "mine.yaml") == 0
    capsys.readouterr()

    def older_witness(data: dict[str, Any]) -> None:  # named by its file, beside it
        data.pop(PROBLEM_SPEC_FIELD)
        data["problem"] = "mine.yaml"

    folder = elsewhere / "suite"
    folder.mkdir()
    (folder / "mine.yaml").write_text(MINE, encoding="utf-8")
    witness = _changed(record, folder, older_witness)
    monkeypatch.chdir(elsewhere.parent)
    assert run_cli(monkeypatch, "replay", str(witness)) == 0
