"""Reading files other people wrote, and writing files so that a failure keeps the old one.

Problem files, settings files, results, records and state files are passed between people,
and a path inside one of them is chosen by whoever wrote it. So every such file is read the
same guarded way (:func:`read_text`): only a regular file (``/dev/zero``, a FIFO or a
terminal would be read forever or block), at most a size limit (read with the bound, never
read whole and measured afterwards), UTF-8; structured text is parsed with a bound on what it
may expand to (:func:`load_yaml`, :func:`load_json`: YAML aliases that stand for billions of
values, JSON nested too deep for the code that walks it). An error quotes a file only as a
short escaped :func:`excerpt`, so a file read by mistake (a record naming ``/etc/shadow`` as
its problem) is never printed.

What stalm writes over an existing file (``--json``, ``--gif``, ``--html``, ``view -o``) is
written beside it under a temporary name and renamed into place (:func:`replacing`): a full
disk or a kill half-way leaves the old file as it was, never a truncated one.

Like :mod:`stalm.errors`, this module sits below every layer, so each can use it.
"""

from __future__ import annotations

import json
import os
import reprlib
import secrets
import stat
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

from stalm.errors import StalmError

MAX_PROBLEM_FILE_BYTES = 1_000_000
"""Problem and settings files: the six problems are 3 to 6 kB, a settings file about 2 kB; a
file a thousand times larger is neither."""
MAX_RESULT_FILE_BYTES = 256 * 1024 * 1024
"""Result, record and state files (a long run's result with its per-step log is a few MB)."""
MAX_VALUES = 100_000
"""Values a YAML or JSON document may hold once aliases are expanded (the problems hold about
a thousand, a result with its step log some ten thousand)."""
MAX_DEPTH = 100
"""Nesting a document may have (stalm's own results nest about ten deep); deeper data would
make the code that walks it recurse past Python's limit."""
EXCERPT_CHARS = 40
"""Characters of a file (or a value from one) an error message may quote."""

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""libyaml's safe loader is fast and limits nesting; the pure-Python one recurses for seconds."""
_SHORT = reprlib.Repr()
_SHORT.maxstring = EXCERPT_CHARS
_SHORT.maxother = EXCERPT_CHARS
_SHORT.maxlist = _SHORT.maxtuple = _SHORT.maxdict = _SHORT.maxset = 4
_SHORT.maxlevel = 3


def excerpt(text: object, limit: int = EXCERPT_CHARS) -> str:
    """A short, escaped quote of ``text``: its first ``limit`` characters as a Python string
    literal (control characters and quotes escaped), with ``...`` when there was more."""
    value = str(text)
    cut = value[:limit]
    return repr(cut) + ("..." if len(value) > limit else "")


def short_repr(value: object) -> str:
    """``repr(value)`` cut short: at most a few items per level and a few levels, strings at
    :data:`EXCERPT_CHARS` (the cost of a huge value's repr is bounded too)."""
    return _SHORT.repr(value)


def read_bytes(path: Path, limit: int, what: str) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them; a StalmError naming
    ``what`` and the path for anything else (missing, a folder, a device, a FIFO, too big)."""
    try:
        info = os.stat(path)
    except OSError as error:
        raise StalmError(f"{path}: cannot read {what} ({error.strerror or error})") from None
    if stat.S_ISDIR(info.st_mode):
        raise StalmError(f"{path}: is a folder, not a {what}")
    if not stat.S_ISREG(info.st_mode):
        raise StalmError(f"{path}: not a regular file (a device, pipe or socket), not a {what}")
    try:
        # O_NONBLOCK: should the path have become a FIFO since the check, open does not wait
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as error:
        raise StalmError(f"{path}: cannot read {what} ({error.strerror or error})") from None
    with os.fdopen(descriptor, "rb") as handle:
        if not stat.S_ISREG(os.fstat(handle.fileno()).st_mode):
            raise StalmError(f"{path}: not a regular file, not a {what}")
        try:
            data = handle.read(limit + 1)
        except OSError as error:
            raise StalmError(f"{path}: cannot read {what} ({error.strerror})") from None
    if len(data) > limit:
        raise StalmError(f"{path}: too long for a {what} (larger than {limit} bytes)")
    return data


def read_text(path: Path, limit: int, what: str) -> str:
    """The UTF-8 text of the regular file ``path`` (see :func:`read_bytes`)."""
    data = read_bytes(path, limit, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise StalmError(
            f"{path}: not a {what} (not UTF-8 text: byte {data[error.start]:#04x} at offset "
            f"{error.start})"
        ) from None


def too_big(data: object, max_values: int = MAX_VALUES, max_depth: int = MAX_DEPTH) -> str | None:
    """Why loaded data is too big to be walked (more than ``max_values`` values with aliases
    expanded, or nested deeper than ``max_depth``), or None. Iterative: a cycle or a
    billion-value alias bomb costs at most ``max_values`` steps."""
    stack: list[tuple[object, int]] = [(data, 1)]
    count = 0
    while stack:
        node, depth = stack.pop()
        count += 1
        if count > max_values:
            return f"more than {max_values} values (aliases expanded)"
        if depth > max_depth:
            return f"nested more than {max_depth} deep"
        if isinstance(node, dict):
            stack.extend((value, depth + 1) for value in node.values())
        elif isinstance(node, list | tuple):
            stack.extend((value, depth + 1) for value in node)
    return None


def load_yaml(text: str, where: str, max_values: int = MAX_VALUES) -> Any:
    """YAML (or JSON) text with a safe loader, refused as one StalmError line naming ``where``
    when it does not parse or stands for too much (:func:`too_big`). The parser's message is
    kept without the quoted line it points at."""
    try:
        data = yaml.load(text, Loader=_LOADER)
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark
        at = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        raise StalmError(f"{where}: not valid YAML: {error.problem or error.context}{at}") from None
    except yaml.YAMLError as error:
        raise StalmError(f"{where}: not valid YAML ({type(error).__name__})") from None
    except (ValueError, OverflowError, RecursionError) as error:  # e.g. date 2001-02-30
        raise StalmError(
            f"{where}: not valid YAML: {type(error).__name__}: {excerpt(error, 80)}"
        ) from None
    why = too_big(data, max_values)
    if why is not None:
        raise StalmError(f"{where}: {why}")
    return data


class _NotFinite(ValueError):
    """JSON's non-standard ``NaN``/``Infinity`` where only finite numbers belong."""


def _no_constant(name: str) -> float:
    raise _NotFinite(name)


def load_json(text: str, where: str, *, finite: bool = False) -> Any:
    """JSON text as data, refused as one StalmError line naming ``where`` when it does not
    parse or nests deeper than :data:`MAX_DEPTH`; with ``finite``, ``NaN`` and ``Infinity``
    (which Python's json reads, and stalm never writes) are refused too."""
    try:
        data = json.loads(text, parse_constant=_no_constant if finite else None)
    except RecursionError:
        raise StalmError(f"{where}: nested more than {MAX_DEPTH} deep") from None
    except _NotFinite as error:
        raise StalmError(f"{where}: {error} is not a finite number (stalm writes none)") from None
    except ValueError as error:  # json.JSONDecodeError is one
        raise StalmError(f"{where}: not JSON ({excerpt(error, 80)})") from None
    why = too_big(data, max_values=50 * MAX_VALUES)
    if why is not None:
        raise StalmError(f"{where}: {why}")
    return data


@contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """A new file beside ``path`` to write; renamed onto ``path`` when the block ends without
    an error, removed when it raises. The name keeps ``path``'s suffix (image writers pick the
    format by it) and the file gets the old file's permissions (a new one: the umask's)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temp = path.with_name(f".{path.stem}-{secrets.token_hex(4)}.partial{path.suffix}")
    os.close(os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        if path.is_file():
            os.chmod(temp, stat.S_IMODE(path.stat().st_mode))
        yield temp
        os.replace(temp, path)
    except BaseException:
        temp.unlink(missing_ok=True)
        raise


def write_replacing(path: Path, data: str | bytes) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` through :func:`replacing`: all or nothing."""
    payload = data.encode("utf-8") if isinstance(data, str) else data
    with replacing(path) as temp, temp.open("wb") as handle:
        handle.write(payload)
        handle.flush()
        os.fsync(handle.fileno())


def write_together(files: Sequence[tuple[Path, str]]) -> None:
    """Write every ``(path, text)`` of ``files`` (UTF-8), all or none: each is first written
    whole beside its path, then renamed into place; should a rename fail (a folder where the
    file goes, a full disk), the files already renamed are put back as they were (an old file
    restored, a new one removed) and the error is raised. Files that belong together (a
    problem and its witness) are never left one without the other."""
    staged: list[tuple[Path, Path]] = []
    swapped: list[tuple[Path, Path | None]] = []  # (path, where its old file waits, or None)
    try:
        for path, text in files:
            temp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.partial")
            staged.append((temp, path))
            with temp.open("xb") as handle:
                handle.write(text.encode("utf-8"))
                handle.flush()
                os.fsync(handle.fileno())
        for temp, path in staged:
            backup = None
            if path.is_file():
                backup = path.with_name(f".{path.name}.{secrets.token_hex(4)}.old")
                os.replace(path, backup)
            swapped.append((path, backup))
            os.replace(temp, path)
    except BaseException:
        for path, backup in reversed(swapped):
            if backup is not None:
                os.replace(backup, path)
            elif path.is_file():
                path.unlink()
        for temp, _ in staged:
            temp.unlink(missing_ok=True)
        raise
    for _, backup in swapped:
        if backup is not None:
            backup.unlink(missing_ok=True)


def read_json_file(path: Path, what: str, *, finite: bool = False) -> Any:
    """The JSON in the regular file ``path`` (at most :data:`MAX_RESULT_FILE_BYTES`), through
    :func:`read_text` and :func:`load_json`: every failure one StalmError naming the path."""
    return load_json(read_text(path, MAX_RESULT_FILE_BYTES, what), str(path), finite=finite)
