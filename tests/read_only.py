"""Making files and folders read-only in a test, also when the tests run as root.

File modes do not stop root, so as root each path is also made immutable (``chattr +i``, which
stops root too); where neither holds (no ``chattr``, a file system without the flag) the test
is skipped rather than passing without having tested anything.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import pytest


def _writable(path: Path) -> bool:
    """Whether this process can still write ``path`` (a folder: create a file in it)."""
    try:
        if path.is_dir():
            probe = path / ".write-probe"
            os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
            probe.unlink()
        else:
            os.close(os.open(path, os.O_WRONLY | os.O_APPEND))
    except OSError:
        return False
    return True


def _chattr(flag: str, paths: list[Path]) -> bool:
    tool = shutil.which("chattr")
    if tool is None:
        return False
    done = subprocess.run([tool, flag, *map(str, paths)], capture_output=True, check=False)
    return done.returncode == 0


@contextmanager
def read_only(*paths: Path) -> Iterator[None]:
    """``paths`` (files first, then their folders) read-only for the block, then writable."""
    listed = list(paths)
    modes = {path: stat.S_IMODE(path.stat().st_mode) for path in listed}
    immutable = False
    try:
        for path in listed:
            os.chmod(path, modes[path] & ~0o222)
        if any(_writable(path) for path in listed):
            immutable = os.geteuid() == 0 and _chattr("+i", listed)
        if any(_writable(path) for path in listed):
            pytest.skip("cannot make a file read-only here (root without chattr +i)")
        yield
    finally:
        if immutable:
            _chattr("-i", listed)
        for path in listed:
            with suppress(OSError):
                os.chmod(path, modes[path])
