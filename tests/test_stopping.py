"""A process stalm starts ends with its parent, also when the parent is killed outright
(issue 46, item 7: ``kill -9`` of an experiment left its workers waiting on their pipe).

A parent process starts a child that calls :func:`stalm.stopping.end_with_parent`, then is
killed with SIGKILL; the child must be sent the signal (it says so in a file and ends). This
machine's init reaps no orphans, so the ended child may stay a zombie: a process that no
longer runs. Everything is polled with generous timeouts; nothing is timed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT_S = 60.0

CHILD = """
import os, signal, sys, time
from stalm import stopping
if sys.argv[1] == "poll":  # as where the kernel offers no parent-death signal
    stopping._parent_death_signal = lambda signum: False
out = sys.argv[3]
def ended(signum, frame):
    with open(out, "a") as f:
        f.write(f"ended by {signal.Signals(signum).name}\\n")
    os._exit(0)
signal.signal(signal.SIGTERM, ended)
stopping.end_with_parent(signal.SIGTERM, int(sys.argv[2]))
with open(out, "a") as f:
    f.write("ready\\n")
time.sleep(120)
"""

PARENT = """
import os, subprocess, sys, time
child = subprocess.Popen([sys.executable, "-c", sys.argv[1], sys.argv[2], str(os.getpid()),
                          sys.argv[3]])
print(child.pid, flush=True)
time.sleep(120)
"""


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT)}


def _poll(condition, what: str) -> None:
    deadline = time.monotonic() + TIMEOUT_S
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"gave up waiting for {what}")
        time.sleep(0.02)


def _running(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, or no process at all, does not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def _said(path: Path) -> list[str]:
    return path.read_text().split("\n")[:-1] if path.exists() else []


@pytest.mark.parametrize("how", ["kernel", "poll"])
def test_a_child_is_sent_its_signal_when_its_parent_is_killed(tmp_path: Path, how: str) -> None:
    said = tmp_path / "child.txt"
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, CHILD, how, str(said)],
        stdout=subprocess.PIPE,
        text=True,
        env=_env(),
        start_new_session=True,
    )
    try:
        assert parent.stdout is not None
        child = int(parent.stdout.readline())
        _poll(lambda: _said(said) == ["ready"], "the child to be ready")
        parent.kill()
        parent.wait()
        _poll(lambda: not _running(child), "the child to end")
        assert _said(said) == ["ready", "ended by SIGTERM"]
    finally:
        with contextlib.suppress(ProcessLookupError):  # whatever is left of the test's
            os.killpg(parent.pid, signal.SIGKILL)
        parent.wait()


def test_a_parent_gone_before_the_call_is_signalled_at_once(tmp_path: Path) -> None:
    said = tmp_path / "child.txt"
    not_the_parent = 1  # init is no stalm process's parent here: the parent "has changed"
    done = subprocess.run(
        [sys.executable, "-c", CHILD, "kernel", str(not_the_parent), str(said)],
        env=_env(),
        timeout=TIMEOUT_S,
        check=False,
    )
    assert done.returncode == 0
    assert _said(said) == ["ended by SIGTERM"]


def test_the_watcher_signals_once_the_parent_is_another(monkeypatch) -> None:
    """In this process, with SIGUSR1 (no test stops on it): the polling watcher signals as
    soon as the parent is not the one named, and where the kernel would send the signal,
    only a parent already gone is signalled at once."""
    from stalm import stopping

    heard: list[int] = []
    previous = signal.signal(signal.SIGUSR1, lambda signum, frame: heard.append(signum))
    try:
        stopping._watch_parent(signal.SIGUSR1, os.getppid() + 1)  # not (or no longer) ours
        _poll(lambda: heard == [signal.SIGUSR1], "the signal")
        monkeypatch.setattr(stopping, "_parent_death_signal", lambda signum: True)
        stopping.end_with_parent(signal.SIGUSR1, os.getppid())  # still ours: nothing now
        stopping.end_with_parent(signal.SIGUSR1, os.getppid() + 1)
        _poll(lambda: heard == [signal.SIGUSR1] * 2, "the second signal")
        # no parent-death signal: a watcher thread (which ends at once here) and the check
        monkeypatch.setattr(stopping, "_parent_death_signal", lambda signum: False)
        stopping.end_with_parent(signal.SIGUSR1, os.getppid() + 1)
        _poll(lambda: heard == [signal.SIGUSR1] * 4, "the watcher's signal and the check's")
    finally:
        signal.signal(signal.SIGUSR1, previous)


STARTER = """
import sys
from stalm import stopping
stopping.run_child([sys.executable, "-c", "import os, time; print(os.getpid(), flush=True); "
                    "time.sleep(120)"], timeout=300)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux's parent-death signal")
def test_a_child_run_to_end_with_its_starter_is_killed_with_it() -> None:
    """As Fast Downward is started: its starter killed with SIGKILL (no ``finally`` runs to
    kill it), the child does not run on for its two minutes."""
    starter = subprocess.Popen(
        [sys.executable, "-c", STARTER],
        stdout=subprocess.PIPE,
        text=True,
        env=_env(),
        start_new_session=True,
    )
    try:
        assert starter.stdout is not None
        child = int(starter.stdout.readline())
        assert _running(child)
        starter.kill()
        starter.wait()
        _poll(lambda: not _running(child), "the child to end with its starter")
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(starter.pid, signal.SIGKILL)
        starter.wait()


def test_run_child_returns_what_subprocess_run_would() -> None:
    """The output and exit code of ``command``, the memory limit set in the child, a command
    that cannot be run (127 and a line, as a shell's), and a timeout that kills the child and
    is raised."""
    from stalm import stopping

    limit = "import resource, sys; print(resource.getrlimit(resource.RLIMIT_AS)); sys.exit(3)"
    done = stopping.run_child(
        [sys.executable, "-c", limit],
        timeout=TIMEOUT_S,
        capture_output=True,
        text=True,
        memory_limit_mb=512,
    )
    assert (done.returncode, done.stdout, done.stderr) == (3, f"{(512 << 20,) * 2}\n", "")
    unlimited = stopping.run_child([sys.executable, "-c", limit], timeout=TIMEOUT_S)
    assert unlimited.returncode == 3
    assert done.args == [sys.executable, "-c", limit]  # the command, not its launcher
    with pytest.raises(FileNotFoundError, match="/no/such/program"):
        stopping.run_child(["/no/such/program"], timeout=TIMEOUT_S)
    with pytest.raises(FileNotFoundError, match="no-such-program-on-the-path"):
        stopping.run_child(["no-such-program-on-the-path"], timeout=TIMEOUT_S)
    with pytest.raises(ValueError, match="memory_limit_mb must be >= 0"):
        stopping.run_child([sys.executable, "-c", ""], timeout=TIMEOUT_S, memory_limit_mb=-1)
    sleep = [sys.executable, "-c", "import time; time.sleep(60)"]
    with pytest.raises(subprocess.TimeoutExpired) as expired:
        stopping.run_child(sleep, timeout=0.5)
    assert expired.value.cmd == sleep


def test_the_launched_program_gets_the_signals_and_limits_subprocess_would_give_it() -> None:
    """SIGPIPE and SIGXFSZ at their defaults (Python ignores them; subprocess restores them),
    as a program started by subprocess.run has them, and a memory limit lowered to a hard
    limit this process already has rather than refused."""
    from stalm import stopping

    ignored = "print(open('/proc/self/status').read().split('SigIgn:')[1].split()[0])"
    direct = subprocess.run(
        [sys.executable, "-c", ignored], capture_output=True, text=True, check=True
    )
    launched = stopping.run_child(
        [sys.executable, "-c", ignored], timeout=TIMEOUT_S, capture_output=True, text=True
    )
    assert launched.stdout == direct.stdout
    limited = "import resource; print(resource.getrlimit(resource.RLIMIT_AS)[0] >> 20)"
    starter = (
        "import resource, sys; from stalm import stopping; "
        "resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30)); "
        f"print(stopping.run_child([sys.executable, '-c', {limited!r}], timeout=60, "
        "memory_limit_mb=8192, capture_output=True, text=True).stdout, end='')"
    )
    done = subprocess.run(
        [sys.executable, "-c", starter], capture_output=True, text=True, env=_env(), check=False
    )
    assert (done.returncode, done.stdout) == (0, "4096\n"), done.stderr


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux's parent-death signal")
def test_the_launcher_of_a_starter_already_gone_runs_nothing() -> None:
    """The starter's pid is passed to the launcher: one whose parent is another by the time
    it has asked for the signal (here: pid 1 named as the starter) kills itself rather than
    run unwatched."""
    from stalm import stopping

    done = subprocess.run(
        [sys.executable, "-I", "-S", "-c", stopping.LAUNCHER, "1", "0", "echo", "ran"],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        check=False,
    )
    assert (done.returncode, done.stdout) == (-signal.SIGKILL, "")


NO_AT_FORK_HOOK = """
import os, sys
from stalm import stopping
ran = []
os.register_at_fork(before=lambda: ran.append(1), after_in_parent=lambda: ran.append(2))
stopping.run_child([sys.executable, "-c", "pass"], timeout=60)
print(ran, flush=True)
"""


def test_a_child_is_started_without_running_this_processs_at_fork_hooks() -> None:
    """Python runs its at-fork hooks around a fork only for a ``preexec_fn``; a stop signal's
    handler run inside one has its Stopped swallowed, and the stop is lost (in a process with
    threads nothing can hold the signal back). run_child needs none, so no hook runs."""
    done = subprocess.run(
        [sys.executable, "-c", NO_AT_FORK_HOOK],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=TIMEOUT_S,
        check=False,
    )
    assert (done.returncode, done.stdout) == (0, "[]\n"), done.stderr


def test_a_stop_swallowed_inside_stops_kept_is_raised_at_its_end() -> None:
    """As an at-fork hook swallows it: the handler's Stopped caught inside the block. It is
    raised again, with its signal, at the block's end; the handler is found whichever stop
    signal the process was started ignoring (here TERM, as a scheduler might)."""
    from stalm import stopping

    # as the process was started: TERM ignored, the others not (whatever this test runner's are)
    started = {signal.SIGTERM: signal.SIG_IGN, signal.SIGINT: signal.SIG_DFL}
    started[signal.SIGHUP] = signal.SIG_DFL
    previous = {number: signal.signal(number, how) for number, how in started.items()}
    try:
        with stopping.stopping_on_signals():
            assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
            with pytest.raises(stopping.Stopped) as stop, stopping.stops_kept():
                handler = signal.getsignal(signal.SIGHUP)
                assert isinstance(handler, stopping.StopHandler)
                with contextlib.suppress(stopping.Stopped):  # swallowed
                    handler(signal.SIGHUP, None)
            assert stop.value.signum == signal.SIGHUP
            with stopping.stops_kept():  # handled: every stop signal ignored, nothing more
                pass
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
