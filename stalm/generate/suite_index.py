"""A suite's index, read and checked: what ``stalm experiment scale`` runs and what making a
suite again compares with (the format is :mod:`stalm.generate.suite`'s)."""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stalm.errors import StalmError
from stalm.files import (
    MAX_PROBLEM_FILE_BYTES,
    MAX_RESULT_FILE_BYTES,
    excerpt,
    read_bytes,
    read_json_file,
)
from stalm.generate.arrange import MAX_OBJECTS

INDEX = "index.json"
SUITE_VERSION = 2
"""2: the index records each file's SHA-256, the suite's sizes and layout, and whether it is
complete; version 1 (no hashes) cannot tell an edited file from the generated one."""
SUITE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")
"""A suite's name: a letter, then up to 63 letters, digits, ``_`` or ``-`` (it names files)."""


@dataclass(frozen=True)
class SuiteProblem:
    """One problem of a suite, as its index names it."""

    file: str
    witness: str
    objects: int
    seed: int
    optimal_length: int
    sha256: str
    """The SHA-256 of the problem file's bytes as written."""
    witness_sha256: str


@dataclass(frozen=True)
class Suite:
    """A suite's index (see the module docstring); ``folder`` is where it was read from."""

    name: str
    seed: int
    knobs: dict[str, Any]
    problems: tuple[SuiteProblem, ...]
    folder: Path
    sizes: tuple[int, ...] = ()
    per_size: int = 0
    layout: str = "kitchen-hall"

    def path(self, problem: SuiteProblem) -> Path:
        return self.folder / problem.file


def check_suite_name(name: str) -> str:
    """``name`` if it is a suite's name (:data:`SUITE_NAME`), else a StalmError: a name with a
    ``/`` or ``..`` would put the suite's files outside its folder."""
    if not SUITE_NAME.fullmatch(name):
        raise StalmError(
            f"--suite {excerpt(name)}: a suite's name is a letter then up to 63 letters, digits, "
            "'_' or '-', not a path (the folder is -o)"
        )
    return name


def file_sha256(path: Path, limit: int) -> str | None:
    """The SHA-256 of the file's bytes, or None if it cannot be read as a regular file."""
    try:
        return hashlib.sha256(read_bytes(path, limit, "suite file")).hexdigest()
    except StalmError:
        return None


def read_suite(folder: Path) -> Suite:
    """The complete suite whose index is in ``folder``, every file checked against the hash
    the index records for it and every problem's number of objects against its file: a
    StalmError naming what is wrong."""
    from stalm.world.problem import load_problem

    suite = read_index(folder, complete=True)
    again = "make the suite again (stalm generate --suite ... --replace)"
    for problem in suite.problems:
        for name, recorded, limit in (
            (problem.file, problem.sha256, MAX_PROBLEM_FILE_BYTES),
            (problem.witness, problem.witness_sha256, MAX_RESULT_FILE_BYTES),
        ):
            if file_sha256(folder / name, limit) != recorded:
                raise StalmError(
                    f"{folder / name}: missing, or differs from the suite's index (edited "
                    f"after it was generated?): {again}"
                )
        count = len(load_problem(suite.path(problem)).spec.objects)
        if count != problem.objects:
            raise StalmError(
                f"{folder / INDEX}: {problem.file} has {count} objects, the index says "
                f"{problem.objects}: {again}"
            )
    return suite


def read_index(folder: Path, *, complete: bool) -> Suite:
    """The index in ``folder`` as written by :func:`generate_suite` (every field of the
    expected kind); ``complete``: refuse an unfinished one."""
    index = folder / INDEX
    if not index.exists():
        raise StalmError(f"{index}: cannot read the suite's index (no such file)")
    data = read_json_file(index, "suite index", finite=True)
    if not isinstance(data, dict) or data.get("suite_version") != SUITE_VERSION:
        version = data.get("suite_version") if isinstance(data, dict) else None
        raise StalmError(
            f"{index}: a suite index of version {excerpt(version)}, not {SUITE_VERSION} (made "
            "before indexes recorded each file's hash): make it again with stalm generate "
            "--suite ... --replace"
        )
    try:
        problems = tuple(_problem_entry(p, index) for p in _field(data, "problems", list))
        suite = Suite(
            name=check_suite_name(_field(data, "suite", str)),
            seed=_field(data, "seed", int),
            knobs=_field(data, "knobs", dict),
            problems=problems,
            folder=folder,
            sizes=tuple(_count(n, "sizes") for n in _field(data, "sizes", list)),
            per_size=_field(data, "per_size", int),
            layout=_field(data, "layout", str),
        )
        finished = _field(data, "complete", bool)
    except StalmError as error:
        raise StalmError(f"{index}: not a suite index ({error})") from None
    if complete and not finished:
        raise StalmError(
            f"{index}: the suite is not finished (its generation stopped): run the same "
            "stalm generate command again to finish it"
        )
    return suite


def _field(data: dict[str, Any], name: str, kind: type) -> Any:
    value = data.get(name)
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise StalmError(f"field {name!r} is {excerpt(value)}, not a {kind.__name__}")
    return value


def _count(value: object, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_OBJECTS:
        raise StalmError(f"field {name!r} holds {excerpt(value)}, not a count 1-{MAX_OBJECTS}")
    return value


def _problem_entry(entry: object, index: Path) -> SuiteProblem:
    if not isinstance(entry, dict):
        raise StalmError(f"a problem entry is {excerpt(entry)}, not a mapping")
    return SuiteProblem(
        file=plain_name(_field(entry, "file", str), index),
        witness=plain_name(_field(entry, "witness", str), index),
        objects=_count(entry.get("objects"), "objects"),
        seed=_field(entry, "seed", int),
        optimal_length=_field(entry, "optimal_length", int),
        sha256=_field(entry, "sha256", str),
        witness_sha256=_field(entry, "witness_sha256", str),
    )


def plain_name(name: str, index: Path) -> str:
    """A file of the suite's own folder: a name, never a path elsewhere."""
    if Path(name).name != name or name in ("", ".", ".."):
        raise StalmError(f"{excerpt(name)} is not a file name in the suite's folder")
    return name
