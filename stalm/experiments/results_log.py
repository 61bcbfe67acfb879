"""The append-only JSON-lines file of trial records, safe to kill at any moment.

Only the experiment's caller writes (workers hand records back), and each record is written
as one ``write`` of one complete line on a file opened for appending, then ``fsync``-ed: a
kill before the write loses only the running trial, a kill after it loses nothing. If the
machine dies inside the write, the file could end in a partial line; reading skips it (with
a warning) and the next append first cuts it off, so the file never holds a corrupt line
next to good ones.

A trial is finished when its last record is not an ``error`` (an exception in a planner):
re-running the same command skips finished trials and retries errored ones.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stalm.errors import StalmError


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
    tail = lines.pop()  # b"" when the file ends with a newline, else a partial last line
    records: list[dict[str, Any]] = []
    problems: list[str] = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except json.JSONDecodeError as error:
            problems.append(f"{path}:{number}: not a JSON record ({error.msg})")
            continue
        if not isinstance(record, dict) or "key" not in record:
            problems.append(f"{path}:{number}: not a trial record (no 'key')")
            continue
        records.append(record)
    return LoadedRecords(
        tuple(records), skipped_partial_line=bool(tail.strip()), problems=tuple(problems)
    )


class ResultsLog:
    """Appends trial records to one JSON-lines file (see the module docstring)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self._path = Path(path)
        try:
            self._path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise StalmError(f"cannot create the results folder {self._path.parent}") from error
        self._cut_partial_tail()

    @property
    def path(self) -> Path:
        return self._path

    def _cut_partial_tail(self) -> None:
        if not self._path.exists():
            return
        with self._path.open("rb+") as handle:
            data = handle.read()
            if data and not data.endswith(b"\n"):
                handle.truncate(data.rfind(b"\n") + 1)

    def append(self, record: dict[str, Any]) -> None:
        line = (json.dumps(record, sort_keys=True, default=str) + "\n").encode()
        descriptor = os.open(self._path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
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
