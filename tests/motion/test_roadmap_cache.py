"""A roadmap cache that cannot be written costs a rebuild, not the run (issue 30, item 8).

When ``$STALM_CACHE_DIR`` is a file, or a folder nobody may write, roadmaps are built in
memory as usual and the run goes on, with one warning naming the folder. The PRM itself is
replaced by a double: what is tested is what happens around it.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from stalm.errors import StalmWarning
from stalm.motion import roadmap as roadmap_module
from stalm.motion.roadmap import Roadmap, RoadmapSettings, load_or_build_roadmap
from tests.read_only import read_only


@pytest.fixture
def built(monkeypatch: pytest.MonkeyPatch) -> list[frozenset[str]]:
    """Every roadmap built (by its open doors); each build returns a two-node roadmap."""
    calls: list[frozenset[str]] = []

    def build(sim: object, open_doors: frozenset[str], settings: RoadmapSettings) -> Roadmap:
        calls.append(open_doors)
        return Roadmap(np.array([[0.0, 0.0], [1.0, 0.0]]), ((1,), (0,)), (), open_doors)

    monkeypatch.setattr(roadmap_module, "build_roadmap", build)
    return calls


def _load_twice(domain_factory, settings: RoadmapSettings) -> list[warnings.WarningMessage]:
    sim = domain_factory("P2").sim
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for doors in (frozenset(), frozenset({"d"}), frozenset()):
            found = load_or_build_roadmap(sim, doors, settings)
            assert found.open_doors == doors and len(found.nodes) == 2
    return [w for w in caught if issubclass(w.category, StalmWarning)]


def test_a_cache_dir_that_is_a_file_builds_in_memory_with_one_warning(
    monkeypatch, tmp_path: Path, domain_factory, built
) -> None:
    not_a_folder = tmp_path / "cache-file"
    not_a_folder.write_text("not a folder")
    monkeypatch.setenv("STALM_CACHE_DIR", str(not_a_folder))
    caught = _load_twice(domain_factory, RoadmapSettings(seed=101))
    assert len(built) == 3  # nothing could be kept, so each is built
    [warning] = caught
    assert f"cannot cache roadmaps in {not_a_folder / 'roadmaps'}" in str(warning.message)
    assert not_a_folder.read_text() == "not a folder"


def test_a_read_only_cache_dir_builds_in_memory_with_one_warning(
    monkeypatch, tmp_path: Path, domain_factory, built
) -> None:
    folder = tmp_path / "cache"
    folder.mkdir()
    monkeypatch.setenv("STALM_CACHE_DIR", str(folder))
    with read_only(folder):
        caught = _load_twice(domain_factory, RoadmapSettings(seed=102))
    assert len(built) == 3
    [warning] = caught
    assert f"cannot cache roadmaps in {folder / 'roadmaps'}" in str(warning.message)
    assert list(folder.iterdir()) == []


def test_a_writable_cache_dir_keeps_each_roadmap_once(
    monkeypatch, tmp_path: Path, domain_factory, built
) -> None:
    monkeypatch.setenv("STALM_CACHE_DIR", str(tmp_path / "cache"))
    assert _load_twice(domain_factory, RoadmapSettings(seed=103)) == []
    assert built == [frozenset(), frozenset({"d"})]  # the third came from the disk
    assert len(list((tmp_path / "cache" / "roadmaps").glob("*.npz"))) == 2


def test_the_command_line_warns_in_one_line(tmp_path: Path) -> None:
    """``stalm problems --file`` checks a scene on its roadmaps: with ``$STALM_CACHE_DIR`` a
    file it still does, and says once, in one line, that nothing was cached."""
    import os
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    not_a_folder = tmp_path / "cache-file"
    not_a_folder.write_text("not a folder")
    env = {**os.environ, "PYTHONPATH": str(root), "STALM_CACHE_DIR": str(not_a_folder)}
    stalm = [sys.executable, "-c", "from stalm.cli.main import main; main()"]
    done = subprocess.run(
        [*stalm, "problems", "--file", str(root / "stalm" / "problems" / "p2.yaml")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if "cannot cache roadmaps" in line]
    assert len(lines) == 1 and lines[0].startswith("warning: cannot cache roadmaps in ")
