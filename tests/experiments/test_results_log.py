"""The results log: whole lines only, partial tails cut, errored trials retried."""

from __future__ import annotations

import json
from pathlib import Path

from stalm.experiments.results_log import ResultsLog, read_records


def _record(key: str, termination: str = "goal") -> dict[str, object]:
    return {
        "key": key,
        "arm": "stalm",
        "problem": "P1",
        "trial": 0,
        "termination": termination,
        "success": termination == "goal",
        "time_s": 1.5,
    }


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
    path.write_text(json.dumps(_record("a")) + "\nnot json\n[1, 2]\n")
    loaded = read_records(path)
    assert [r["key"] for r in loaded.records] == ["a"]
    assert any(":2: not a JSON record" in p for p in loaded.problems)
    assert any(":3: not a trial record" in p for p in loaded.problems)


def test_a_missing_file_has_no_records(tmp_path: Path) -> None:
    assert read_records(tmp_path / "none.jsonl").records == ()


# --- Issue 16: every complete record kept, unreadable lines named and set aside --------------


def test_a_last_record_missing_only_its_newline_is_kept_on_read_and_resume(
    tmp_path: Path,
) -> None:
    path = tmp_path / "r.jsonl"
    path.write_text(json.dumps(_record("a")) + "\n" + json.dumps(_record("b")))
    loaded = read_records(path)
    assert [r["key"] for r in loaded.records] == ["a", "b"]
    assert not loaded.skipped_partial_line and not loaded.problems
    log = ResultsLog(path)
    assert log.load().finished_keys() == {"a", "b"}  # b is not re-run
    log.append(_record("c"))
    assert [json.loads(line)["key"] for line in path.read_text().splitlines()] == ["a", "b", "c"]


def test_a_partial_tail_cut_on_resume_is_set_aside_not_lost(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    path.write_text(json.dumps(_record("a")) + "\n" + '{"key": "b", "termi')
    log = ResultsLog(path)
    assert log.set_aside is not None and log.set_aside.exists()
    assert log.set_aside.read_text() == '{"key": "b", "termi\n'
    assert read_records(path).records[0]["key"] == "a"


def test_a_line_that_is_not_utf8_is_named_and_the_rest_kept(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    good = [json.dumps(_record(k)).encode() for k in ("a", "b")]
    path.write_bytes(good[0] + b"\n" + b'{"key": "\xff\xfe"}\n' + good[1] + b"\n")
    loaded = read_records(path)
    assert [r["key"] for r in loaded.records] == ["a", "b"]
    assert len(loaded.problems) == 1 and ":2:" in loaded.problems[0]
    assert "UTF-8" in loaded.problems[0]
    assert ResultsLog(path).load().finished_keys() == {"a", "b"}


def test_records_missing_or_mistyping_fields_are_named_and_skipped(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    no_arm = {k: v for k, v in _record("x").items() if k != "arm"}
    bad_time = _record("y") | {"time_s": "soon"}
    nan_time = _record("z") | {"time_s": float("nan")}
    bad_failures = _record("w") | {"llm_plan_failures": {"unparseable": "many"}}
    lines = [_record("a"), no_arm, bad_time, nan_time, bad_failures, _record("b")]
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    loaded = read_records(path)
    assert [r["key"] for r in loaded.records] == ["a", "b"]
    assert len(loaded.problems) == 4
    assert ":2:" in loaded.problems[0] and "'arm'" in loaded.problems[0]
    assert "'time_s'" in loaded.problems[1] and "'time_s'" in loaded.problems[2]
    assert "'llm_plan_failures'" in loaded.problems[3]


def test_report_and_resume_go_on_past_unreadable_lines(tmp_path: Path, capsys) -> None:
    import sys

    import pytest

    from stalm.cli.main import main

    path = tmp_path / "r.jsonl"
    no_arm = {k: v for k, v in _record("x").items() if k != "arm"}
    path.write_bytes(
        json.dumps(_record("a")).encode()
        + b"\n\xff\xfe garbage\n"
        + json.dumps(no_arm).encode()
        + b"\n"
        + json.dumps(_record("b", "timeout")).encode()
    )
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sys, "argv", ["stalm", "report", str(path), "--out", str(tmp_path)])
        with pytest.raises(SystemExit) as done:
            main()
    assert done.value.code in (None, 0)
    captured = capsys.readouterr()
    assert "| stalm |" in captured.out and "(1/2)" in captured.out
    assert f"{path}:2:" in captured.err and f"{path}:3:" in captured.err
