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


def test_a_run_unwound_by_a_stop_also_removes_its_own_folders(tmp_path: Path) -> None:
    dead = _dead_pid()
    mine = tmp_path / f"stalm-fd-{os.getpid()}-abcd"
    theirs = tmp_path / f"stalm-trial-{dead}-abcd"
    alive = tmp_path / f"stalm-trial-{os.getppid()}-abcd"  # another run, still going
    for folder in (mine, theirs, alive):
        folder.mkdir()
    assert remove_leftovers(tmp_path) == [theirs]
    assert mine.is_dir()
    assert remove_leftovers(tmp_path, mine_too=True) == [mine]
    assert alive.is_dir()


def _mkdtemp_then_stopped(monkeypatch, signum: int) -> list[str]:
    """Make ``tempfile.mkdtemp`` in :mod:`stalm.temp_folders` make its folder and then raise
    Stopped, as a signal that arrives right after the ``mkdir`` does (CI saw one, issue 41's
    stop 50: a HUP during a solve left ``stalm-fd-*`` behind)."""
    import tempfile

    from stalm.stopping import Stopped

    real = tempfile.mkdtemp
    made: list[str] = []

    def made_then_stopped(*args, **kwargs) -> str:
        made.append(real(*args, **kwargs))
        raise Stopped(signum)

    monkeypatch.setattr("stalm.temp_folders.tempfile.mkdtemp", made_then_stopped)
    return made


def test_a_stop_inside_mkdtemp_leaves_no_folder_after_a_solve(monkeypatch, tmp_path: Path) -> None:
    import signal

    from tests.cli_runner import run_cli

    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    made = _mkdtemp_then_stopped(monkeypatch, signal.SIGHUP)
    code = run_cli(monkeypatch, "solve", "P2", "--proposer", "symbolic")
    assert code == 128 + signal.SIGHUP
    assert len(made) == 1 and Path(made[0]).name.startswith("stalm-fd-")
    assert list(tmp_path.iterdir()) == []


def test_a_worker_stopped_inside_mkdtemp_removes_its_folder(monkeypatch, tmp_path: Path) -> None:
    import signal

    from stalm.experiments import runner

    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    made = _mkdtemp_then_stopped(monkeypatch, signal.SIGTERM)

    def trial_making_a_folder(spec: object) -> dict[str, object]:
        with temporary_folder("trial"):
            raise AssertionError("the stop came first")

    class Exited(Exception):
        pass

    def exit_raising(code: int) -> None:
        raise Exited(code)

    monkeypatch.setattr(runner, "run_trial", trial_making_a_folder)
    monkeypatch.setattr(runner.os, "_exit", exit_raising)
    with pytest.raises(Exited) as exited:
        runner.run_trial_in_worker(object())  # type: ignore[arg-type]
    assert exited.value.args == (128 + signal.SIGTERM,)
    assert len(made) == 1 and list(tmp_path.iterdir()) == []
