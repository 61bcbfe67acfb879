"""The results log: whole lines only, partial tails cut, errored trials retried."""

from __future__ import annotations

import json
from pathlib import Path

from stalm.experiments.results_log import ResultsLog, read_records


def _record(key: str, termination: str = "goal") -> dict[str, object]:
    return {"key": key, "termination": termination, "success": termination == "goal"}


def test_append_then_load_keeps_order_and_fields(tmp_path: Path) -> None:
    log = ResultsLog(tmp_path / "sub" / "r.jsonl")
    log.extend([_record("a"), _record("b", "timeout")])
    loaded = log.load()
    assert [r["key"] for r in loaded.records] == ["a", "b"]
    assert loaded.records[1]["termination"] == "timeout"
    assert log.path.read_text().count("\n") == 2


def test_errored_trials_are_not_finished_until_a_later_record(tmp_path: Path) -> None:
    log = ResultsLog(tmp_path / "r.jsonl")
    log.extend([_record("a"), _record("b", "error")])
    assert log.load().finished_keys() == {"a"}
    log.append(_record("b", "timeout"))
    assert log.load().finished_keys() == {"a", "b"}
    assert log.load().latest_by_key()["b"]["termination"] == "timeout"


def test_a_partial_last_line_is_skipped_and_cut_before_the_next_append(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    path.write_text(json.dumps(_record("a")) + "\n" + '{"key": "b", "termi')
    loaded = read_records(path)
    assert loaded.skipped_partial_line
    assert [r["key"] for r in loaded.records] == ["a"]
    log = ResultsLog(path)
    log.append(_record("c"))
    lines = path.read_text().splitlines()
    assert [json.loads(line)["key"] for line in lines] == ["a", "c"]


def test_lines_that_are_not_records_are_reported_with_their_line_number(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    path.write_text('{"key": "a"}\nnot json\n[1, 2]\n')
    loaded = read_records(path)
    assert [r["key"] for r in loaded.records] == ["a"]
    assert any(":2: not a JSON record" in p for p in loaded.problems)
    assert any(":3: not a trial record" in p for p in loaded.problems)


def test_a_missing_file_has_no_records(tmp_path: Path) -> None:
    assert read_records(tmp_path / "none.jsonl").records == ()
