"""One writer per results file: the lock a ``stalm experiment`` run holds on it.

Two runs on one results file (two shells, two Ray drivers) would each run every trial and
append conflicting records. So a run takes an exclusive ``flock`` on ``NAME.jsonl.lock``
beside the file before it reads which trials are finished, and holds it until it ends; a
second run finds the lock taken and stops before any trial (:class:`ResultsBusy`), naming the
running one by the host and process id it wrote into the lock file.

The operating system releases a ``flock`` when its holder dies however it dies, so a lock file
left by a killed run blocks nothing: its text is only information, never trusted. The file is
left in place (removing it would let a third run lock a new file while a second still waits on
the old one).
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from stalm.errors import StalmError
from stalm.files import excerpt

LOCK_SUFFIX = ".lock"
_HOLDER_BYTES = 200
"""How much of a lock file is read to name its holder (what stalm writes is one short line)."""


class ResultsBusy(StalmError):
    """Another run holds the results file's lock (the CLI exits 1, not 2: nothing is wrong
    with the command, the file is taken)."""


def lock_path(results: Path) -> Path:
    """The lock file of the results file ``results``: beside it, with ``.lock`` added."""
    return results.with_name(results.name + LOCK_SUFFIX)


def _holder(descriptor: int) -> str:
    """Who the lock file says holds it, as an escaped excerpt (or that it does not say)."""
    try:
        text = os.pread(descriptor, _HOLDER_BYTES, 0).decode("utf-8", "replace").strip()
    except OSError:
        text = ""
    return excerpt(text, 120)[1:-1] if text else "no host or process named"


@contextmanager
def results_lock(results: Path) -> Iterator[Path]:
    """Hold the exclusive lock of ``results`` for the block; :class:`ResultsBusy` at once if
    another process holds it, a StalmError if the lock file cannot be made."""
    path = lock_path(results)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as error:
        raise StalmError(f"cannot lock {results}: {path} ({error.strerror or error})") from None
    try:
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            if error.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise StalmError(
                    f"cannot lock {results}: {path} ({error.strerror or error})"
                ) from None
            raise ResultsBusy(
                f"{results} is being written by another stalm experiment ({_holder(descriptor)});"
                " wait for it to end, or name another file with --results"
            ) from None
        since = time.strftime("%Y-%m-%d %H:%M:%S")
        holder = f"host {socket.gethostname()}, process {os.getpid()}, since {since}\n"
        os.ftruncate(descriptor, 0)
        os.pwrite(descriptor, holder.encode("utf-8"), 0)
        try:
            yield path
        finally:
            os.ftruncate(descriptor, 0)  # the lock is let go when the descriptor closes
    finally:
        os.close(descriptor)
