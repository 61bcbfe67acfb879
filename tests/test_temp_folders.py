"""stalm's temporary folders carry the id of the process that made them, and a later run
removes those whose process is gone, and only those (issue 46, item 7: ``kill -9`` of a
solve left its folder in the system's temporary folder for good)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from stalm.temp_folders import process_alive, remove_leftovers, temporary_folder


def _dead_pid() -> int:
    """The id of a process that has ended (and been waited for)."""
    done = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        check=True,
        capture_output=True,
        text=True,
    )
    return int(done.stdout)


def test_a_folder_is_named_with_its_kind_and_process(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    with temporary_folder("trial") as folder:
        assert Path(folder).parent == tmp_path
        assert Path(folder).name.startswith(f"stalm-trial-{os.getpid()}-")
        assert remove_leftovers(tmp_path) == []  # its process is this one: alive
        assert Path(folder).is_dir()
    assert not Path(folder).exists()
    with pytest.raises(ValueError, match="kind"), temporary_folder("other"):
        pass


def test_a_stop_in_the_middle_of_the_removal_still_removes_the_folder(
    monkeypatch, tmp_path: Path
) -> None:
    """A TERM that arrives while the folder is being removed raises Stopped inside the
    removal; the folder is removed all the same, and the stop goes on."""
    import shutil

    from stalm.stopping import Stopped

    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    real = shutil.rmtree
    calls: list[str] = []

    def rmtree_stopped_once(path: str, ignore_errors: bool = False) -> None:
        calls.append(path)
        if len(calls) == 1:
            (Path(path) / "half").unlink()  # part of the folder went before the signal
            raise Stopped(15)
        real(path, ignore_errors=ignore_errors)

    monkeypatch.setattr("stalm.temp_folders.shutil.rmtree", rmtree_stopped_once)
    with pytest.raises(Stopped), temporary_folder("fd") as folder:
        (Path(folder) / "half").write_text("x")
        (Path(folder) / "output.sas").write_text("begin_version")
    assert calls == [folder, folder]
    assert not Path(folder).exists()


def test_the_folders_of_ended_processes_are_removed_and_no_other(tmp_path: Path) -> None:
    dead = _dead_pid()
    assert not process_alive(dead)
    leftovers = [tmp_path / f"stalm-{kind}-{dead}-x1y2" for kind in ("trial", "fd")]
    for folder in leftovers:
        (folder / "inside").mkdir(parents=True)
        (folder / "inside" / "task.sas").write_text("begin_version")
    kept = [
        tmp_path / f"stalm-trial-{os.getpid()}-abcd",  # a run still going
        tmp_path / f"stalm-fd-{os.getppid()}-abcd",
        tmp_path / "stalm-trial-0-abcd",  # not a process id
        tmp_path / f"stalm-bench-fd-{dead}-abcd",  # not a kind of stalm-trial's
        tmp_path / "stalm-trial-abcd",  # no process in the name (an older stalm's)
        tmp_path / f"stalm-result-{dead}-abcd.json",
    ]
    for folder in kept[:-1]:
        folder.mkdir()
    kept[-1].write_text("{}")  # a file, not a folder
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    link = tmp_path / f"stalm-trial-{dead}-link"
    link.symlink_to(outside)  # never followed
    assert sorted(remove_leftovers(tmp_path)) == sorted(leftovers)
    assert all(not folder.exists() for folder in leftovers)
    assert all(path.exists() for path in [*kept, link, outside])
    assert remove_leftovers(tmp_path / "missing") == []


def test_process_alive() -> None:
    assert process_alive(os.getpid())
    assert process_alive(1)  # init: alive, whoever's it is
    assert process_alive(0) and process_alive(-1)  # groups, not processes: never "dead"
    assert process_alive(2**70)  # not a pid at all: left alone


def test_every_command_starts_by_removing_leftovers(monkeypatch, tmp_path: Path) -> None:
    from tests.cli_runner import run_cli

    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    leftover = tmp_path / f"stalm-fd-{_dead_pid()}-abcd"
    leftover.mkdir()
    assert run_cli(monkeypatch, "planners") == 0
    assert not leftover.exists()
