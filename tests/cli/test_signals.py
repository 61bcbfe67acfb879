"""A signal a scheduler sends stops the whole run and removes its temporary files (issue 30,
item 6).

``stalm solve`` is stopped while Fast Downward runs, and ``stalm experiment --workers 2``
while its workers run trials, by TERM, INT or HUP sent to stalm's own process only (as ``kill
PID`` does). Each run gets a session of its own and a temporary folder of its own (``TMPDIR``):
afterwards no process of the session is left, not even a zombie (this machine's init reaps no
orphans, so an orphan that ends stays one), and the folder is empty. Everything is polled
with generous timeouts; nothing is timed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from stalm.experiments.results_log import read_records

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT_S = 240.0


def _session(sid: int) -> list[str]:
    """The processes of session ``sid`` (pid, state and name), zombies included."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue  # ended meanwhile
        name = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[3]) == sid:
            found.append(f"{entry.name} {fields[0]} {name}")
    return found


def _running(sid: int) -> list[str]:
    """The processes of session ``sid`` that still run (not zombies: an orphan that ended
    stays one here, its parent killed and this machine's init reaping nothing)."""
    return [entry for entry in _session(sid) if entry.split()[1] != "Z"]


def _poll(
    condition: Callable[[], bool], what: str | Callable[[], str], timeout_s: float = TIMEOUT_S
) -> None:
    """Wait for ``condition``; ``what`` (or what it returns, read at the time) names it."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"gave up waiting for {what() if callable(what) else what}")
        time.sleep(0.02)


def _why_alive(sid: int) -> str:
    """What each process of session ``sid`` still running is doing: its parent, where the
    kernel has it wait (``wchan``) and its signal masks. TERM (bit 15, 0x4000) pending in
    ``SigPnd``/``ShdPnd`` means its handler has not run yet (a long C call); TERM in
    ``SigIgn`` means the handler ran and the process is unwinding."""
    lines = []
    for entry in _running(sid):
        pid = entry.split()[0]
        try:
            status = Path(f"/proc/{pid}/status").read_text().splitlines()
            wchan = Path(f"/proc/{pid}/wchan").read_text()
        except OSError:
            continue  # ended meanwhile
        keep = ("PPid", "SigPnd", "ShdPnd", "SigBlk", "SigIgn", "SigCgt", "Threads")
        fields = [line.replace("\t", "") for line in status if line.split(":")[0] in keep]
        lines.append(f"{entry} wchan={wchan or '-'} " + " ".join(fields))
    return "; ".join(lines)


def _foreground_signals() -> None:
    """As a command typed at a terminal starts: INT and HUP not ignored (this test may run in
    a background job, whose INT is ignored, which stalm then leaves ignored, as Python does)."""
    for number in (signal.SIGINT, signal.SIGHUP):
        signal.signal(number, signal.SIG_DFL)


def _start(tmp_path: Path, *args: str) -> tuple[subprocess.Popen[bytes], Path]:
    """``stalm ARGS`` in a session of its own with its own empty TMPDIR."""
    temp = tmp_path / "tmp"
    temp.mkdir()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(temp)}
    process = subprocess.Popen(
        [sys.executable, "-c", "from stalm.cli.main import main; main()", *args],
        stdout=subprocess.DEVNULL,
        stderr=(tmp_path / "stderr.txt").open("wb"),
        env=env,
        start_new_session=True,
        preexec_fn=_foreground_signals,
    )
    return process, temp


def _stop_and_check(
    process: subprocess.Popen[bytes], temp: Path, signum: int, tmp_path: Path
) -> None:
    os.kill(process.pid, signum)
    try:
        code = process.wait(timeout=TIMEOUT_S)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    stderr = (tmp_path / "stderr.txt").read_text(errors="replace")
    assert code == 128 + signum, stderr  # stopped itself, was not killed by the signal
    assert "Traceback" not in stderr, stderr
    _poll(lambda: not _session(process.pid), f"the processes of the run: {_session(process.pid)}")
    assert sorted(p.name for p in temp.iterdir()) == []


def test_a_signal_started_ignored_stays_ignored() -> None:
    """``nohup`` ignores HUP (a shell's background job INT): stalm keeps it so."""
    code = (
        "import signal; from stalm.stopping import stopping_on_signals\n"
        "with stopping_on_signals():\n"
        "    print(signal.getsignal(signal.SIGHUP) is signal.SIG_IGN,"
        " signal.getsignal(signal.SIGTERM) not in (signal.SIG_IGN, signal.SIG_DFL))"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        ["nohup", sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        check=True,
    )
    assert done.stdout.split() == ["True", "True"]


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_signal_during_fast_downward_stops_solve_and_cleans_up(
    tmp_path: Path, signum: int
) -> None:
    process, temp = _start(
        tmp_path, "solve", "P2", "--proposer", "symbolic", "--time-budget", "200"
    )
    try:
        # Fast Downward runs while its folder exists (one per query, a few per solve)
        _poll(lambda: any(temp.glob("stalm-fd-*")) or process.poll() is not None, "Fast Downward")
        assert process.poll() is None, "the solve ended before Fast Downward ran"
    except BaseException:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        raise
    _stop_and_check(process, temp, signum, tmp_path)


@pytest.mark.slow
def test_sigterm_stops_an_experiment_with_its_workers(tmp_path: Path) -> None:
    results = tmp_path / "results.jsonl"
    process, temp = _start(
        tmp_path,
        "experiment",
        "table2",
        "--problems",
        "P2",
        "--planners",
        "stalm-symbolic",
        "--trials",
        "4",
        "--workers",
        "2",
        "--time-budget",
        "200",
        "--results",
        str(results),
    )
    try:
        # both workers are in a trial, one of them in Fast Downward
        _poll(
            lambda: (
                (len(list(temp.glob("stalm-trial-*"))) == 2 and any(temp.glob("stalm-fd-*")))
                or process.poll() is not None
            ),
            "two trials, one in Fast Downward",
        )
        assert process.poll() is None, "the experiment ended before its trials ran"
    except BaseException:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        raise
    _stop_and_check(process, temp, signal.SIGTERM, tmp_path)
    loaded = read_records(results)
    assert not loaded.problems and not loaded.skipped_partial_line
    assert "run the same command to resume" in " ".join(
        (tmp_path / "stderr.txt").read_text().split()
    )


KILLED_RUN_ENDS_S = 10.0
"""How long the processes of an experiment killed with SIGKILL may take to notice it (polled:
the test passes as soon as they are gone)."""


def _next_run(temp: Path) -> None:
    """A next stalm command, with the killed run's temporary folder."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(temp)}
    code = "from stalm.cli.main import main; main()"
    subprocess.run(
        [sys.executable, "-c", code, "planners"],
        env=env,
        stdout=subprocess.DEVNULL,
        timeout=TIMEOUT_S,
        check=True,
    )


@pytest.mark.slow
def test_kill_9_of_an_experiment_ends_its_workers_and_the_next_run_clears_up(
    tmp_path: Path,
) -> None:
    process, temp = _start(
        tmp_path,
        "experiment",
        "table2",
        "--problems",
        "P1",
        "--planners",
        "stalm-symbolic",
        "--trials",
        "4",
        "--workers",
        "2",
        "--time-budget",
        "30",
        "--results",
        str(tmp_path / "results.jsonl"),
    )
    try:
        _poll(
            lambda: len(list(temp.glob("stalm-trial-*"))) == 2 or process.poll() is not None,
            "two trials running",
        )
        assert process.poll() is None, "the experiment ended before its trials ran"
        assert len(_running(process.pid)) >= 3  # itself and two workers (and their helpers)
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        # the workers (about 450 MB each) and the resource tracker do not outlive it
        _poll(
            lambda: not _running(process.pid),
            lambda: f"the processes of the killed run to end: {_why_alive(process.pid)}",
            KILLED_RUN_ENDS_S,
        )
        _next_run(temp)
        assert sorted(p.name for p in temp.iterdir()) == []
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()


@pytest.mark.slow
def test_the_folder_a_solve_killed_with_kill_9_leaves_goes_with_the_next_run(
    tmp_path: Path,
) -> None:
    process, temp = _start(
        tmp_path, "solve", "P2", "--proposer", "symbolic", "--time-budget", "200"
    )
    try:
        _poll(lambda: any(temp.glob("stalm-fd-*")) or process.poll() is not None, "Fast Downward")
        assert process.poll() is None, "the solve ended before Fast Downward ran"
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        # Fast Downward (its translator or its search) is killed with it, not left running
        _poll(
            lambda: not _running(process.pid),
            lambda: f"Fast Downward to end with the killed solve: {_why_alive(process.pid)}",
            KILLED_RUN_ENDS_S,
        )
        left = [p.name for p in temp.iterdir()]
        assert left and all(name.startswith(f"stalm-fd-{process.pid}-") for name in left), left
        _next_run(temp)
        assert sorted(p.name for p in temp.iterdir()) == []
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
