"""Every limit a command or a problem file enforces is in `--help` and in the format's docs
(issue 42, finding 5: `--objects 128` was refused with "at most 120", said nowhere)."""

from __future__ import annotations

from pathlib import Path

import pytest

from stalm.files import MAX_PROBLEM_FILE_BYTES
from stalm.generate.arrange import MAX_DEPTH, MAX_GOALS, MAX_OBJECTS
from stalm.viz.render import MAX_SIZE, MIN_SIZE
from stalm.world.spec_values import MAX_EXTENT, MAX_FLOOR_SIDE
from tests.cli_runner import run_cli

PROBLEMS_PAGE = Path(__file__).resolve().parents[2] / "docs" / "problems.md"


def _help(monkeypatch: pytest.MonkeyPatch, capsys, command: str) -> str:
    monkeypatch.setenv("COLUMNS", "400")  # one line per option: no limit cut in two
    assert run_cli(monkeypatch, command, "--help") == 0
    return " ".join(capsys.readouterr().out.split())


def test_generate_help_states_its_limits(monkeypatch, capsys) -> None:
    text = _help(monkeypatch, capsys, "generate")
    assert f"at most {MAX_OBJECTS}" in text  # --objects
    assert f"each 1-{MAX_OBJECTS}" in text  # --sizes
    assert f"(1-{MAX_GOALS})" in text and f"(0-{MAX_DEPTH})" in text


def test_render_help_states_its_size_limits(monkeypatch, capsys) -> None:
    assert f"({MIN_SIZE}-{MAX_SIZE})" in _help(monkeypatch, capsys, "render")


def test_problems_help_states_a_problem_files_limits(monkeypatch, capsys) -> None:
    text = _help(monkeypatch, capsys, "problems")
    assert MAX_PROBLEM_FILE_BYTES == 1_000_000 and "at most 1 MB" in text
    assert f"+-{MAX_EXTENT:g}" in text and f"at most {MAX_FLOOR_SIDE:g} m on a side" in text
    assert "up to 64 letters" in text


def test_the_format_page_states_every_limit() -> None:
    page = " ".join(PROBLEMS_PAGE.read_text(encoding="utf-8").split())
    assert "at most 1 MB" in page
    assert f"within ±{MAX_EXTENT:g}" in page and f"at most {MAX_FLOOR_SIDE:g} m on a side" in page
    assert "up to 64 letters" in page
    assert f"at most {MAX_OBJECTS}" in page and f"1-{MAX_GOALS}" in page
    assert f"0-{MAX_DEPTH}" in page and f"{MIN_SIZE}-{MAX_SIZE} pixels" in page


def test_objects_beyond_the_limit_are_refused_as_the_help_says(monkeypatch, capsys, tmp_path):
    out = tmp_path / "g.yaml"
    code = run_cli(monkeypatch, "generate", "--objects", str(MAX_OBJECTS + 8), "-o", str(out))
    assert code == 2
    assert (
        f"--objects must be at most {MAX_OBJECTS}, got {MAX_OBJECTS + 8}" in capsys.readouterr().err
    )
    assert not out.exists()


def test_solve_help_says_what_runs_when_no_model_is_named(monkeypatch, capsys) -> None:
    """`--llm`'s help said 'embedded' was the default, where STaLM with no model named runs
    on the symbolic proposer (as docs/llm.md now says too; issue 42, finding 6)."""
    text = _help(monkeypatch, capsys, "solve")
    assert "'embedded' (default)" not in text
    assert "None named: STaLM runs on the symbolic proposer" in text


def test_export_help_states_its_rate_limits(monkeypatch, capsys) -> None:
    from stalm.trial.export import RATE_RANGE

    low, high = RATE_RANGE
    assert f"({low:g}-{high:g} Hz)" in _help(monkeypatch, capsys, "export")
