"""Output paths checked before any work starts, and results that outlive a failed write.

A solve can take minutes; learning only afterwards that ``--json`` names a folder would throw
its result away. :func:`check_output_file` runs before planning; :func:`write_or_fall_back`
still keeps a result whose write fails later (a full disk, a folder removed meanwhile) by
writing it to a temporary file it names.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from stalm.errors import StalmError
from stalm.files import write_replacing


def check_output_file(path: Path, option: str) -> None:
    """A StalmError naming ``option`` and the path if a file cannot be written at ``path``."""
    if path.is_dir():
        raise StalmError(f"{option} {path}: is a folder; name a file to write")
    ancestor = path.parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise StalmError(f"{option} {path}: {ancestor} is a file, not a folder")
    if not os.access(ancestor, os.W_OK | os.X_OK) or not _can_create_in(ancestor):
        raise StalmError(f"{option} {path}: cannot write in {ancestor}")
    if path.exists() and not os.access(path, os.W_OK):
        raise StalmError(f"{option} {path}: the file is not writable")


def _can_create_in(folder: Path) -> bool:
    """Can a file be made in ``folder``? Tried, not inferred from permission bits: they do not
    stop root, nor tell of a read-only file system or a kernel folder such as ``/proc``."""
    try:
        handle, name = tempfile.mkstemp(prefix=".stalm-write-check-", dir=folder)
    except OSError:
        return False
    os.close(handle)
    Path(name).unlink(missing_ok=True)
    return True


def write_or_fall_back(text: str, path: Path, stem: str) -> tuple[Path, str | None]:
    """Write ``text`` to ``path`` all or nothing (beside it, then renamed: a failure leaves
    the old file); if that fails, to a new temporary file.

    Returns the path written and, after a fallback, why ``path`` failed. A StalmError naming
    both when neither can be written (a full disk everywhere).
    """
    try:
        write_replacing(path, text)
        return path, None
    except OSError as error:
        why = error.strerror or str(error)
    handle, name = tempfile.mkstemp(
        prefix=f"{stem}-{time.strftime('%Y%m%d-%H%M%S')}-", suffix=".json"
    )
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as fallback:
            fallback.write(text)
    except OSError as error:
        Path(name).unlink(missing_ok=True)
        raise StalmError(
            f"{path}: cannot write it ({why}), nor a copy in {Path(name).parent} "
            f"({error.strerror or error})"
        ) from None
    return Path(name), why
