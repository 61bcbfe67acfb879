"""stalm's temporary folders, named by the process that made them, and their leftovers.

A trial writes its problem file into a folder of its own, Fast Downward works in another, and
each is removed when its block ends, also when a signal stops the run (:mod:`stalm.stopping`).
Nothing runs after ``kill -9`` (or the out-of-memory killer), so such a folder stays in the
system's temporary folder. Each folder's name carries the id of the process that made it
(``stalm-trial-4242-xxxxxxxx``), so that a later run can tell a leftover from the folder of a
run still going: :func:`remove_leftovers` removes the folders whose process is gone, and
only those (a process of another user, or one it cannot see, counts as alive).

Like :mod:`stalm.errors`, this module sits below every layer.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

KINDS = ("trial", "fd", "pddlstream", "ray")
"""What the folders are for: a trial's problem file, a Fast Downward run, PDDLStream's Fast
Downward run, a Ray task's copy of the reply cache."""

_NAME = re.compile(rf"stalm-(?:{'|'.join(KINDS)})-([0-9]{{1,10}})-")


@contextmanager
def temporary_folder(kind: str) -> Iterator[str]:
    """A new temporary folder for ``kind`` (one of :data:`KINDS`) named with this process's
    id, removed when its ``with`` block ends.

    A stop signal raises :class:`~stalm.stopping.Stopped` wherever the process is, also in
    the middle of removing the folder as its block ends normally; the removal is then done
    again (the handler ignores every later stop signal, so the second one runs to its end)
    before the stop goes on. A folder cut half-removed was left behind otherwise."""
    if kind not in KINDS:
        raise ValueError(f"unknown kind of temporary folder {kind!r}")
    path = tempfile.mkdtemp(prefix=f"stalm-{kind}-{os.getpid()}-")
    try:
        yield path
    finally:
        try:
            shutil.rmtree(path, ignore_errors=True)
        except BaseException:
            shutil.rmtree(path, ignore_errors=True)
            raise


def process_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (one of another user's counts; so does a zombie)."""
    if pid <= 0:
        return True  # not a process id: 0 and -1 name groups of processes; leave it be
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def remove_leftovers(root: Path | None = None, *, mine_too: bool = False) -> list[Path]:
    """Remove the stalm folders in ``root`` (default: the system's temporary folder) whose
    process has ended, and return them. Only this user's folders, never a symbolic link;
    a folder that cannot be listed or removed is left (the next run tries again).

    ``mine_too`` also removes this process's own folders: for a run that a stop signal has
    unwound, when none of them is in use any more. A signal that arrives inside
    :func:`tempfile.mkdtemp`, after the folder is made and before :func:`temporary_folder`'s
    ``try`` holds it, leaves that folder behind otherwise (a handler runs between any two
    bytecodes; blocking the signals around the call would not cover a signal delivered to
    another thread, whose handler still runs in the main one)."""
    root = Path(tempfile.gettempdir()) if root is None else root
    own = os.getpid() if mine_too else None
    removed: list[Path] = []
    try:
        entries = list(os.scandir(root))
    except OSError:
        return removed
    me = os.getuid() if hasattr(os, "getuid") else None
    for entry in entries:
        found = _NAME.match(entry.name)
        if found is None:
            continue
        pid = int(found.group(1))
        if pid != own and process_alive(pid):
            continue
        try:
            if not entry.is_dir(follow_symlinks=False):
                continue
            if me is not None and entry.stat(follow_symlinks=False).st_uid != me:
                continue
        except OSError:
            continue
        shutil.rmtree(entry.path, ignore_errors=True)
        if not os.path.lexists(entry.path):
            removed.append(Path(entry.path))
    return removed
