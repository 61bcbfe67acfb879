"""The append-only JSON-lines file of trial records, safe to kill at any moment.

Only the experiment's caller writes (workers hand records back), and each record is written
as one ``write`` of one complete line on a file opened for appending, then ``fsync``-ed: a
kill before the write loses only the running trial, a kill after it loses nothing. If the
machine dies inside the write, the file could end in a partial line; reading skips it (with
a warning) and the next append first moves it to ``NAME.jsonl.set-aside`` (named in the
warning), so the file never holds a corrupt line next to good ones and no byte is thrown away.
A last line that is a whole record missing only its newline is a record: it is kept and
given its newline.

Reading never stops at a bad line: a line that is not UTF-8, not JSON, or not a trial record
(a field the report needs is missing, of the wrong type or out of range: see
:func:`record_problem`) is skipped and named (``file:line: why``, the why naming the field) in
:attr:`LoadedRecords.problems`; every other record is kept. This is the one reader of records
(resuming an experiment and the report both read through it), so a record the report counts
is in today's shape (:func:`stalm.trial.records.upgraded`) and has been checked as a problem
file is: no count of objects that is no count, no negative or
astronomical time.

A trial is finished when its last record is not an ``error`` (an exception in a planner):
re-running the same command skips finished trials and retries errored ones.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stalm.errors import StalmError
from stalm.files import short_repr
from stalm.trial.records import upgraded

REQUIRED_FIELDS: dict[str, type] = {
    "key": str,
    "arm": str,
    "problem": str,
    "termination": str,
}
"""Fields every trial record has (what resuming and the report group by), with their types."""

_NUMBER_FIELDS = ("time_s", "time_budget_s")
MAX_RECORD_SECONDS = 1e7
"""A trial's time and budget in a record: at most 10^7 s (about 116 days), which no trial
takes; beyond it a mean is nonsense (``1e308`` printed a 300-digit one)."""
MAX_RECORD_OBJECTS = 10_000
"""A record's ``objects`` (a scale trial's number of movable objects): 1 to this many."""
_OPTIONAL_TEXT = ("problem_sha", "problem_hash", "suite")
"""Optional fields that, when present, are text (the report groups by the first two)."""
SET_ASIDE_SUFFIX = ".set-aside"


def record_problem(record: object) -> str | None:
    """Why ``record`` is not a trial record the report and resume can use, or None."""
    if not isinstance(record, dict):
        return f"not a trial record (a JSON {type(record).__name__}, not an object)"
    for name, kind in REQUIRED_FIELDS.items():
        if name not in record:
            return f"not a trial record (no {name!r})"
        if not isinstance(record[name], kind):
            return f"not a trial record ({name!r} is not a string)"
    if not isinstance(record.get("success", False), bool):
        return "not a trial record ('success' is not true or false)"
    for name in _NUMBER_FIELDS:
        value = record.get(name, 0.0)
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not number or not math.isfinite(value):
            return f"not a trial record ({name!r} is not a finite number)"
        if not 0 <= value <= MAX_RECORD_SECONDS:
            return (
                f"not a trial record ({name!r} is {short_repr(value)}, not 0 to "
                f"{MAX_RECORD_SECONDS:g} seconds)"
            )
    if "objects" in record:
        objects = record["objects"]
        whole = isinstance(objects, int) and not isinstance(objects, bool)
        if not whole or not 1 <= objects <= MAX_RECORD_OBJECTS:
            return (
                f"not a trial record ('objects' is {short_repr(objects)}, not a whole number "
                f"1 to {MAX_RECORD_OBJECTS})"
            )
    for name in _OPTIONAL_TEXT:
        if name in record and not isinstance(record[name], str):
            return f"not a trial record ({name!r} is {short_repr(record[name])}, not text)"
    for name in ("started_at", "finished_at"):
        value = record.get(name, 0.0)
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not number or not math.isfinite(value):
            return f"not a trial record ({name!r} is {short_repr(value)}, not a finite time)"
    if record.get("success") and "time_s" not in record:
        return "not a trial record (a success without 'time_s')"
    failures = record.get("llm_plan_failures") or {}
    if not isinstance(failures, dict) or not all(
        isinstance(n, int) and not isinstance(n, bool) for n in failures.values()
    ):
        return "not a trial record ('llm_plan_failures' is not a mapping of counts)"
    return None


def _parse_line(line: bytes) -> tuple[dict[str, Any] | None, str | None]:
    """A record from one line, or None and why not."""
    try:
        text = line.decode("utf-8")
    except UnicodeDecodeError as error:
        return None, f"not UTF-8 text (byte {line[error.start]:#04x} at column {error.start + 1})"
    try:
        record = json.loads(text)
    except json.JSONDecodeError as error:
        return None, f"not a JSON record ({error.msg})"
    except RecursionError:
        return None, "not a JSON record (nested too deeply)"
    problem = record_problem(record)
    return (None, problem) if problem else (record, None)


@dataclass(frozen=True)
class LoadedRecords:
    """The records of a log, in file order, and what could not be read."""

    records: tuple[dict[str, Any], ...]
    skipped_partial_line: bool = False
    problems: tuple[str, ...] = field(default_factory=tuple)

    def latest_by_key(self) -> dict[str, dict[str, Any]]:
        """The last record of each trial key (a retried trial's newest outcome)."""
        latest: dict[str, dict[str, Any]] = {}
        for record in self.records:
            latest[str(record.get("key"))] = record
        return latest

    def finished_keys(self) -> set[str]:
        return {k for k, r in self.latest_by_key().items() if r.get("termination") != "error"}


def read_records(path: Path) -> LoadedRecords:
    """Every complete record of ``path`` (missing file: none)."""
    if not path.exists():
        return LoadedRecords(())
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise StalmError(f"cannot read results {path}: {error}") from error
    lines = raw.split(b"\n")
    tail = lines.pop()  # b"" when the file ends with a newline, else the unfinished last line
    partial = False
    if tail.strip():
        if _parse_line(tail)[0] is not None:
            lines.append(tail)  # a whole record that only lacks its newline
        else:
            partial = True
    records: list[dict[str, Any]] = []
    problems: list[str] = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        record, problem = _parse_line(line)
        if record is None:
            problems.append(f"{path}:{number}: {problem}")
            continue
        records.append(upgraded(record))
    return LoadedRecords(tuple(records), skipped_partial_line=partial, problems=tuple(problems))


class ResultsLog:
    """Appends trial records to one JSON-lines file (see the module docstring)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self._path = Path(path)
        try:
            self._path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise StalmError(f"cannot create the results folder {self._path.parent}") from error
        if self._path.is_dir():
            raise StalmError(f"results file {self._path} is a folder; name a .jsonl file")
        self.set_aside: Path | None = None
        """Where a partial last line was moved on opening (None: there was none)."""
        try:
            self._finish_last_line()
        except OSError as error:
            raise StalmError(f"cannot open results {self._path}: {error.strerror}") from error

    @property
    def path(self) -> Path:
        return self._path

    def _finish_last_line(self) -> None:
        """Give a whole last record its newline; move a partial one to the set-aside file."""
        if not self._path.exists():
            return
        with self._path.open("rb+") as handle:
            data = handle.read()
            if not data or data.endswith(b"\n"):
                return
            start = data.rfind(b"\n") + 1
            tail = data[start:]
            if _parse_line(tail)[0] is not None:
                handle.write(b"\n")
                return
            set_aside = self._path.with_name(self._path.name + SET_ASIDE_SUFFIX)
            with set_aside.open("ab") as kept:
                kept.write(tail + b"\n")
                kept.flush()
                os.fsync(kept.fileno())
            handle.truncate(start)
            self.set_aside = set_aside

    def append(self, record: dict[str, Any]) -> None:
        line = (json.dumps(record, sort_keys=True, default=str) + "\n").encode()
        try:
            descriptor = os.open(self._path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        except OSError as error:
            raise StalmError(f"cannot write results {self._path}: {error.strerror}") from error
        try:
            written = os.write(descriptor, line)
            if written != len(line):  # a short write to a regular file means a full disk
                raise StalmError(f"could not write a whole record to {self._path} (disk full?)")
            os.fsync(descriptor)
        finally:
            os.close(descriptor)

    def extend(self, records: Iterable[dict[str, Any]]) -> None:
        for record in records:
            self.append(record)

    def load(self) -> LoadedRecords:
        return read_records(self._path)
