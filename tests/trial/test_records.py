"""Old records are read through one reader in one place (:mod:`stalm.trial.records`): every
record committed under docs/results, whichever stalm wrote it, comes out in today's shape --
its phase times today's :class:`PhaseTimes` fields with the same seconds, its settings tree
one that ``stalm rerun`` builds -- and a file there that holds no records is refused in one
line or set apart by the results log's reader, never half-read."""

from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path
from typing import Any

import pytest

from stalm.errors import StalmError
from stalm.experiments.results_log import read_records
from stalm.settings.io import from_mapping
from stalm.trial.records import read_record, read_result, upgraded
from stalm.trial.result import PhaseTimes

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"
FILES = sorted(p for p in RESULTS.rglob("*.json*") if p.suffix in (".json", ".jsonl"))
NOT_RECORDS = {
    "issue13/p5-tail.jsonl": "a per-step benchmark of one P5 trial's tail",
    "issue13/fast-downward-scaling.jsonl": "Fast Downward's grounding sizes",
}
"""JSON-lines files under docs/results that hold measurements of another kind."""
PHASES = {f.name for f in fields(PhaseTimes)}
_LOADED_SETTINGS: set[str] = set()


def _name(path: Path) -> str:
    return path.relative_to(RESULTS).as_posix()


def _check_today(raw: dict[str, Any], record: dict[str, Any], where: str) -> None:
    """``record`` (``raw`` read by the reader) has today's shape and loses nothing."""
    times = raw.get("times")
    if isinstance(times, dict):
        assert set(record["times"]) <= PHASES, where
        PhaseTimes(**record["times"])  # every key a field of today's phase times
        for old, new in (("llm", "proposer"),):
            if old in times:
                assert record["times"][new] == times.get(new, times[old]), where
        assert record["times"]["total"] == times["total"], where
    assert {k: v for k, v in record.items() if k != "times"} == {
        k: v for k, v in raw.items() if k != "times"
    }, where
    settings = record.get("settings")
    if isinstance(settings, dict):
        text = json.dumps(settings, sort_keys=True)
        if text not in _LOADED_SETTINGS:  # many records share one tree: each tree once
            from_mapping(settings, f"{where}: settings")
            _LOADED_SETTINGS.add(text)


@pytest.mark.parametrize("path", FILES, ids=_name)
def test_every_committed_record_reads_in_todays_shape(path: Path) -> None:
    name = _name(path)
    if path.suffix == ".json":
        raw = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(raw, dict):  # a benchmark's rows
            with pytest.raises(StalmError, match="not a stalm result"):
                read_result(path)
            return
        _check_today(raw, read_result(path), name)
        return
    lines = [line for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]
    loaded = read_records(path)
    assert not loaded.skipped_partial_line
    if name in NOT_RECORDS:
        assert loaded.records == () and len(loaded.problems) == len(lines)
        return
    assert loaded.problems == () and len(loaded.records) == len(lines) > 0
    for number, (line, record) in enumerate(zip(lines, loaded.records, strict=True), 1):
        _check_today(json.loads(line), record, f"{name}:{number}")


def test_the_files_are_every_record_file_there() -> None:
    assert len(FILES) > 90
    assert {p.suffix for p in FILES} == {".json", ".jsonl"}
    assert set(NOT_RECORDS) <= {_name(p) for p in FILES}


def test_an_old_records_llm_seconds_are_the_proposers_and_the_new_key_wins() -> None:
    old = {"times": {"llm": 1.5, "total": 5.0}, "plan": []}
    assert upgraded(old) == {"times": {"proposer": 1.5, "total": 5.0}, "plan": []}
    assert old == {"times": {"llm": 1.5, "total": 5.0}, "plan": []}  # not changed in place
    both = {"times": {"llm": 1.0, "proposer": 2.0}}
    assert upgraded(both)["times"] == {"proposer": 2.0}
    today = {"times": {"proposer": 2.0}}
    assert upgraded(today) is today
    assert upgraded({"times": None}) == {"times": None}


def test_rerun_reads_a_logs_line_through_the_same_reader(tmp_path: Path) -> None:
    log = tmp_path / "log.jsonl"
    lines = [
        {"key": "abc1", "times": {"llm": 3.0, "total": 4.0}},
        {"key": "def2", "times": {"proposer": 1.0}},
    ]
    log.write_text("".join(json.dumps(line) + "\n" for line in lines))
    assert read_record(log, "abc")["times"] == {"proposer": 3.0, "total": 4.0}
    with pytest.raises(StalmError, match="2 records; choose one with --key"):
        read_record(log, None)
    with pytest.raises(StalmError, match="no record with a key starting 'zz'"):
        read_record(log, "zz")
