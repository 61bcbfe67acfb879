"""A write that fails half-way (a full disk) leaves the file that was there (issue 30, item 5).

The disk is made full for one process by its file-size limit (``RLIMIT_FSIZE``: a write past
it fails with EFBIG, Python ignoring the SIGXFSZ that comes with it): the writers that
``--json``, ``--gif`` and ``stalm view -o`` / ``--html`` use run in a child process with a
limit below what they write, over an existing file that must come out intact, and no
temporary file may be left beside it.
"""

from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

import pytest

from stalm.errors import StalmError

OLD = "the old file, which a failed write must not destroy\n"

JSON_WRITER = """
import sys
from pathlib import Path
from stalm.cli.solve_output import write_result_json
from stalm.errors import StalmError
try:
    write_result_json({"problem": "P2", "blob": "x" * 3_000_000}, Path(sys.argv[1]))
except StalmError as error:
    print("error:", error)
"""

GIF_WRITER = """
import sys
from pathlib import Path
import numpy as np
from PIL import Image
from stalm.viz.animate import save_gif
from stalm.errors import StalmError
rng = np.random.default_rng(0)
frames = [Image.fromarray(rng.integers(0, 255, (300, 300, 3), dtype=np.uint8)) for _ in range(8)]
try:
    save_gif(frames, Path(sys.argv[1]))
except StalmError as error:
    print("error:", error)
"""

PAGE_WRITER = """
import sys
from pathlib import Path
from stalm.viz.view_page import write_page
from stalm.errors import StalmError
try:
    write_page({"problem": "P2", "result": {"planner": "uct"}}, Path(sys.argv[1]))
except StalmError as error:
    print("error:", error)
"""


def _with_full_disk(script: str, target: Path, limit: int) -> subprocess.CompletedProcess[str]:
    def limit_file_size() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))

    return subprocess.run(
        [sys.executable, "-c", script, str(target)],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=limit_file_size,
        check=False,
    )


@pytest.mark.parametrize(
    ("script", "name", "limit"),
    [
        (JSON_WRITER, "result.json", 1_000_000),
        (GIF_WRITER, "plan.gif", 200_000),
        (PAGE_WRITER, "page.html", 1_000_000),
    ],
)
def test_a_full_disk_leaves_the_old_file(tmp_path: Path, script: str, name: str, limit: int):
    target = tmp_path / name
    target.write_text(OLD)
    run = _with_full_disk(script, target, limit)
    assert "Traceback" not in run.stderr, run.stderr
    assert run.stdout.startswith("error:"), (run.stdout, run.stderr)
    assert target.read_text() == OLD
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no half-written leftovers


def test_a_write_that_succeeds_replaces_the_file_and_keeps_its_mode(tmp_path: Path) -> None:
    from stalm.files import write_replacing

    target = tmp_path / "result.json"
    target.write_text(OLD)
    target.chmod(0o640)
    write_replacing(target, "new")
    assert target.read_text() == "new"
    assert target.stat().st_mode & 0o777 == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.json"]


def test_a_failed_gif_does_not_skip_the_html(monkeypatch, tmp_path: Path) -> None:
    from stalm.cli import solve_output, view_commands

    pages: list[Path] = []

    def failing_gif(problem, result, path, *rest):  # type: ignore[no-untyped-def]
        raise StalmError(f"--gif {path}: cannot write it (No space left on device)")

    monkeypatch.setattr(solve_output, "write_gif", failing_gif)
    monkeypatch.setattr(
        view_commands, "write_view_page", lambda problem, data, path: pages.append(path)
    )
    monkeypatch.setattr(solve_output, "result_record", lambda result, problem, settings: {})
    with pytest.raises(StalmError, match="--gif"):
        solve_output.write_pictures(
            None,  # type: ignore[arg-type]
            None,  # type: ignore[arg-type]
            None,  # type: ignore[arg-type]
            tmp_path / "p.gif",
            tmp_path / "p.html",
        )
    assert pages == [tmp_path / "p.html"]
