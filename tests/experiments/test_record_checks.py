"""Trial records are checked as they are read (one reader: ``experiment`` resuming and
``report``): numbers out of range or of the wrong kind are skipped with a line naming the file,
the line and the field, never a crash or a nonsense mean; labels cannot break the Markdown; and
a cell never pools records of two versions of a problem file (the newest version counts)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from stalm.experiments.problem_versions import newest_problem_versions
from stalm.experiments.report import write_report
from stalm.experiments.results_log import read_records
from stalm.experiments.scale_report import markdown_scale, scale_cells
from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli


def _record(key: str, **fields: Any) -> dict[str, Any]:
    return {
        "key": key,
        "arm": "uct",
        "problem": "tiny_000",
        "success": True,
        "termination": "goal",
        "time_s": 4.0,
        "time_budget_s": 30.0,
        "suite": "tiny",
        "objects": 8,
        "problem_sha": "aaaaaaaaaaaa",
        **fields,
    }


def _write(path: Path, records: list[dict[str, Any]]) -> Path:
    lines = [json.dumps(r) for r in records]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("objects", 0),
        ("objects", -3),
        ("objects", 10**400),
        ("objects", 5.5),
        ("objects", True),
        ("objects", "8"),
        ("time_s", -23.4),
        ("time_s", 1e308),
        ("time_budget_s", 1e308),
        ("problem_sha", 7),
    ],
)
def test_a_field_out_of_range_is_skipped_naming_file_line_and_field(
    tmp_path: Path, field: str, value: object
) -> None:
    path = _write(tmp_path / "r.jsonl", [_record("1"), _record("2", **{field: value})])
    loaded = read_records(path)
    assert [r["key"] for r in loaded.records] == ["1"]
    (problem,) = loaded.problems
    assert problem.startswith(f"{path}:2: ") and repr(field) in problem


@pytest.mark.parametrize(
    "fields",
    [{"objects": 0}, {"objects": 10**400}, {"time_s": -23.4}, {"time_s": 1e308}, {"objects": 5.5}],
)
def test_report_on_odd_numbers_is_a_warning_not_a_crash(
    monkeypatch, capsys, tmp_path: Path, fields: dict[str, Any]
) -> None:
    path = tmp_path / "scale.jsonl"
    odd = _record("2", **{"objects": 16, **fields})
    records = [_record("1"), odd, _record("3", objects=16, time_s=8.0)]
    _write(path, records)
    assert run_cli(monkeypatch, "report", str(path), "--out", str(tmp_path / "out")) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    assert f"{path}:2:" in captured.err  # the skipped line, named
    assert "| uct | 1/1, 4.0 s | 1/1, 8.0 s | 1.00 |" in captured.out
    assert "-23" not in captured.out


def test_a_file_of_only_bad_records_is_one_error_line(monkeypatch, capsys, tmp_path) -> None:
    path = _write(tmp_path / "scale.jsonl", [_record("1", objects=0)])
    assert run_cli(monkeypatch, "report", str(path), "--out", str(tmp_path)) == 2
    assert "no trial records" in one_error_line(capsys.readouterr().err)


def test_scale_cells_leave_out_counts_that_are_no_count() -> None:
    records = [_record("1"), _record("2", objects=0), _record("3", objects=True)]
    assert list(scale_cells(records)) == [("uct", 8)]


@pytest.mark.parametrize("label", ["uct | injected | row", "two\nlines", "back\\|slash"])
def test_an_arm_label_cannot_break_the_markdown(tmp_path: Path, label: str) -> None:
    records = [
        _record("1", arm=label, problem="P1", objects=None),
        _record("2", arm="uct", problem="P1", objects=None),
        _record("3", arm=label, problem="P2", objects=None, llm_plan_failures={"other": 1}),
    ]
    for record in records:
        del record["objects"]
    text, _ = write_report(records, tmp_path, formats=())
    scale = markdown_scale(scale_cells([_record("4", arm=label), _record("5")]))
    for table in (text, scale):
        rows = [line for line in table.splitlines() if line.startswith("|")]
        widths = {_columns(line) for line in rows}
        assert len(widths) <= 2, table  # the main table and Figure 5's: each of one width
        assert all(_columns(line) == _columns(rows[0]) for line in rows[:3])


def _columns(line: str) -> int:
    """Cells of a Markdown table line: pipes not escaped with a backslash."""
    count, escaped = 0, False
    for char in line:
        if char == "|" and not escaped:
            count += 1
        escaped = char == "\\" and not escaped
    return count


# ---------------------------------------------------------------------------------------------
# records of two versions of one problem file are never pooled


def test_the_newest_version_of_a_problem_counts_and_the_older_is_named() -> None:
    old = [_record(str(i), problem_sha="0" * 12, finished_at=100.0 + i) for i in range(2)]
    new = [
        _record(
            str(i + 5),
            problem_sha="1" * 12,
            success=False,
            termination="timeout",
            finished_at=200.0 + i,
        )
        for i in range(2)
    ]
    kept, notes = newest_problem_versions([*new[:1], *old, *new[1:]])
    assert kept == new
    (note,) = notes
    assert "tiny_000" in note and "0" * 12 in note and "1" * 12 in note


def test_a_report_of_two_versions_counts_only_the_newest(monkeypatch, capsys, tmp_path) -> None:
    old = [_record(str(i), problem_sha="0" * 12, finished_at=100.0) for i in range(2)]
    new = [
        _record(
            str(i + 5),
            problem_sha="1" * 12,
            success=False,
            termination="timeout",
            finished_at=200.0,
        )
        for i in range(2)
    ]
    path = _write(tmp_path / "scale.jsonl", old + new)
    assert run_cli(monkeypatch, "report", str(path), "--out", str(tmp_path / "out")) == 0
    captured = capsys.readouterr()
    assert "| uct | 0/2, t/o |" in captured.out  # not "2/4"
    assert "warning:" in captured.err and "tiny_000" in captured.err
    assert "left out" in (tmp_path / "out" / "scale.md").read_text()
