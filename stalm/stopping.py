"""Stopping on the signals a scheduler sends: TERM, INT and HUP end stalm one way.

Python dies at once on SIGTERM and SIGHUP: no ``finally`` runs, so a Fast Downward child runs
on as an orphan, ``stalm-fd-*`` and trial folders stay in the temporary folder, and an
experiment's workers go on without their caller. SIGINT's KeyboardInterrupt does unwind, but
``subprocess.run`` gives a killed child only a quarter second to be waited for, and the CLI
framework turns it into "Aborted!". :func:`stopping_on_signals` turns all three into one
exception, :class:`Stopped`, raised where the main thread is; unwinding then runs every
clean-up on the way (``subprocess.run`` kills its child and waits for it, temporary folders
are removed, a worker pool is terminated and joined), and the command exits with 128 + the
signal's number. After the first signal the next ones are ignored, so that a scheduler's
second TERM or an impatient second Ctrl-C cannot cut the clean-up short (it is bounded: a
worker that does not stop is killed).

``kill -9`` runs nothing, so a process stalm started cannot be told by its parent: an
experiment's workers would wait on their pipe for ever (each holding its scene and model).
:func:`end_with_parent` has a process sent a signal when its parent dies, so that it stops
as a signal stops it (a worker unwinds its trial, removing its folders and Fast Downward).
Fast Downward's and V-HACD's processes are started to be killed with their starter
(:func:`run_child`, on Linux): a process killed outright leaves no search running.

:func:`end_helper_processes` stops multiprocessing's resource tracker, which Python 3.11 leaves
to end on its own after stalm has exited: an orphan, which an init that reaps nothing (some
containers) keeps as a zombie. Like :mod:`stalm.errors`, this module sits below every layer.
"""

from __future__ import annotations

import ctypes
import errno
import gc
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from types import FrameType
from typing import Any

STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)
"""What a scheduler, Ctrl-C, a closed terminal or ``kill PID`` sends to end a process."""


class Stopped(BaseException):
    """A TERM, INT or HUP signal arrived. Not an :class:`Exception`, so the ``except Exception``
    that keeps a planner's bug as a trial's error record does not keep it too."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"stopped by {signal.Signals(signum).name}")
        self.signum = signum

    @property
    def exit_code(self) -> int:
        """The shell's convention for a command ended by a signal."""
        return 128 + self.signum


class StopHandler:
    """The handler of the stop signals: the first one ignores the next ones (so that a second
    TERM or Ctrl-C cannot cut the clean-up short) and raises :class:`Stopped` (:meth:`stop`).
    It remembers what it received, for :func:`stops_kept`."""

    def __init__(self) -> None:
        self.received: list[int] = []

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.received.append(signum)
        for number in STOP_SIGNALS:
            signal.signal(number, signal.SIG_IGN)
        self.stop(signum)

    def stop(self, signum: int) -> None:
        """What the first stop signal does once the next ones are ignored."""
        raise Stopped(signum)


@contextmanager
def stops_kept() -> Iterator[None]:
    """Raise at the block's end a stop whose :class:`Stopped` was swallowed inside it.

    ``os.fork`` runs Python's at-fork hooks (``logging`` registers some), and a stop signal
    whose handler runs inside a hook has its exception swallowed ("Exception ignored"); the
    handler has already made every stop signal ignored, so the stop would be lost for good.
    Holding the signals back around the fork does not cover a process with other threads
    (the kernel hands the signal to one that does not block it, and the handler still runs
    in the main thread). A stop raised inside the block as usual propagates as usual."""
    handlers = [signal.getsignal(number) for number in STOP_SIGNALS]  # TERM may be ignored
    handler = next((h for h in handlers if isinstance(h, StopHandler)), None)
    seen = 0 if handler is None else len(handler.received)
    yield
    if handler is not None and len(handler.received) > seen:
        handler.stop(handler.received[seen])


@contextmanager
def stopping_on_signals() -> Iterator[None]:
    """Raise :class:`Stopped` on TERM, INT or HUP inside the block, then restore the handlers that
    were there (the block may be one command run inside a longer-lived process, as tests do).
    Only the main thread can have signal handlers; elsewhere this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = {number: signal.getsignal(number) for number in STOP_SIGNALS}
    install()
    try:
        yield
    finally:
        for number, handler in before.items():
            signal.signal(number, handler)


def install() -> None:
    """Raise :class:`Stopped` in this process's main thread on TERM, INT or HUP from now on.

    A signal the process was started ignoring stays ignored: ``nohup`` ignores HUP and a
    shell's background job INT, so that closing the terminal or a Ctrl-C there does not end it
    (Python itself leaves an ignored SIGINT alone for the same reason)."""
    handler = StopHandler()
    for number in STOP_SIGNALS:
        if signal.getsignal(number) is not signal.SIG_IGN:
            signal.signal(number, handler)


def stop_message(stop: BaseException) -> str:
    """``stopped by SIGTERM``: what ended a run (a :class:`Stopped` or a KeyboardInterrupt)."""
    return str(stop) if isinstance(stop, Stopped) else "stopped by SIGINT"


def stop_code(stop: BaseException) -> int:
    """The exit code of a run ended by ``stop`` (a :class:`Stopped` or a KeyboardInterrupt)."""
    return stop.exit_code if isinstance(stop, Stopped) else 128 + signal.SIGINT


def end_helper_processes() -> None:
    """Stop multiprocessing's resource tracker if this process started one, and wait for it.

    Called last, when no pool is left: the pool's semaphores tell the tracker they are gone as
    they are collected (hence ``gc.collect`` first), and one told after the tracker stopped
    would start another; while a child process of multiprocessing lives (it holds the tracker
    open) nothing is done. ``_stop`` is the standard library's own (private) way to end it."""
    import multiprocessing
    from multiprocessing import resource_tracker

    gc.collect()
    if multiprocessing.active_children():
        return  # they hold the tracker open: stopping it would wait for them
    tracker = getattr(resource_tracker, "_resource_tracker", None)
    stop = getattr(tracker, "_stop", None)
    if stop is None or getattr(tracker, "_pid", None) is None:
        return
    # semaphores a stopped run still holds (its pool's, referenced until exit) are unlinked
    # and unregistered first, as multiprocessing does at exit; stopped with them registered,
    # the tracker would unlink them itself and their finalizers would then fail at exit
    from multiprocessing import util

    run_finalizers = getattr(util, "_run_finalizers", None)
    if run_finalizers is not None:
        run_finalizers(0)
    stop()


PR_SET_PDEATHSIG = 1
"""Linux's prctl option: the signal a process gets when its parent ends."""
PARENT_POLL_S = 0.5
"""Where there is no parent-death signal, how often a process looks whether its parent is
still the one it started with."""


def end_with_parent(signum: int, parent: int) -> None:
    """Have this process sent ``signum`` when ``parent`` (the pid of its parent, read in the
    parent before the process was started) ends.

    On Linux the kernel sends it (``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread
    looks every :data:`PARENT_POLL_S` seconds whether the parent changed (an orphan is
    adopted by another). A parent that ended before this was called is found by its pid: the
    signal is then sent at once."""
    if not (sys.platform.startswith("linux") and _parent_death_signal(signum)):
        watcher = threading.Thread(
            target=_watch_parent, args=(signum, parent), name="stalm-parent-watch", daemon=True
        )
        watcher.start()
    if os.getppid() != parent:
        os.kill(os.getpid(), signum)


LAUNCHER = """
import os, sys
parent, memory_mb, command = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3:]
try:
    if sys.platform.startswith("linux"):
        import ctypes
        if ctypes.CDLL(None).prctl(1, 9, 0, 0, 0) == 0 and os.getppid() != parent:
            os.kill(os.getpid(), 9)  # SIGKILL: the starter ended before this asked
    if memory_mb:
        import resource
        hard = resource.getrlimit(resource.RLIMIT_AS)[1]
        size = memory_mb << 20
        size = size if hard == resource.RLIM_INFINITY else min(size, hard)
        resource.setrlimit(resource.RLIMIT_AS, (size, size))
    import signal
    for name in ("SIGPIPE", "SIGXFSZ"):  # Python ignores them; subprocess restores them
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_DFL)
    os.execvp(command[0], command)
except Exception as error:
    sys.stderr.write(f"cannot run {command[0]}: {error}\\n")
    os._exit(127)
"""
"""What :func:`run_child` runs first, in a Python of its own (isolated, no site packages):
``LAUNCHER STARTER_PID MEMORY_MB COMMAND...``."""


def run_child(
    command: Sequence[str],
    *,
    timeout: float,
    memory_limit_mb: int | None = None,
    **options: Any,
) -> subprocess.CompletedProcess[Any]:
    """``subprocess.run(command, timeout=timeout, check=False, **options)`` for a child (Fast
    Downward, V-HACD) that must not outlive this process: on Linux the kernel kills it when
    this process ends, also by ``kill -9`` or the out-of-memory killer, where no ``finally``
    runs to kill it (an orphaned search would run on unbounded: its time limit is this
    process's timeout). ``memory_limit_mb`` caps the child's address space (at most the hard
    limit this process already has). A program that is not there or not executable raises
    FileNotFoundError, as from ``subprocess.run``.

    The child starts as :data:`LAUNCHER`, which asks for the parent-death signal, sets the
    limit and replaces itself with ``command`` (one more Python start-up: 10-20 ms). A
    ``preexec_fn`` would do both inside the fork, but with one Python runs its at-fork hooks
    around the fork, and a stop signal whose handler runs inside a hook has its
    :class:`Stopped` swallowed ("Exception ignored"): the stop is lost. Nothing can hold the
    signal back there in a process with other threads (the kernel hands it to one that does
    not block it). The parent-death signal is tied to the calling thread, which waits here
    until the child has ended."""
    if memory_limit_mb is not None and (
        isinstance(memory_limit_mb, bool) or not isinstance(memory_limit_mb, int)
    ):
        raise ValueError(f"memory_limit_mb must be a whole number, got {memory_limit_mb!r}")
    if memory_limit_mb is not None and memory_limit_mb < 0:
        raise ValueError(f"memory_limit_mb must be >= 0, got {memory_limit_mb}")
    _check_runnable(command[0], options.get("cwd"), options.get("env"))
    launcher = [sys.executable, "-I", "-S", "-c", LAUNCHER, str(os.getpid())]
    memory = str(memory_limit_mb or 0)
    try:
        done = subprocess.run(
            [*launcher, memory, *command], timeout=timeout, check=False, **options
        )
    except subprocess.TimeoutExpired as expired:  # named by the command, not the launcher
        raise subprocess.TimeoutExpired(
            list(command), timeout, output=expired.output, stderr=expired.stderr
        ) from None
    done.args = list(command)
    return done


def _check_runnable(program: str, cwd: str | os.PathLike[str] | None, env: Any) -> None:
    """FileNotFoundError unless ``program`` (a path, relative to ``cwd``, or a name looked up
    on the ``PATH`` of ``env``) is an executable file."""
    found: bool
    if os.path.dirname(program):
        path = os.path.join(cwd, program) if cwd is not None else program
        found = os.path.isfile(path) and os.access(path, os.X_OK)
    else:
        search = (os.environ if env is None else env).get("PATH")
        found = shutil.which(program, path=search) is not None
    if not found:
        raise FileNotFoundError(errno.ENOENT, "no executable program", program)


def _parent_death_signal(signum: int) -> bool:
    """Ask Linux for ``signum`` when the parent ends; False if that cannot be asked."""
    prctl = getattr(_C_LIBRARY, "prctl", None)
    return prctl is not None and int(prctl(PR_SET_PDEATHSIG, signum, 0, 0, 0)) == 0


def _watch_parent(signum: int, parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(PARENT_POLL_S)
    os.kill(os.getpid(), signum)


def _c_library() -> ctypes.CDLL | None:
    try:
        return ctypes.CDLL(None, use_errno=True)
    except OSError:
        return None


_C_LIBRARY = _c_library() if sys.platform.startswith("linux") else None
"""The C library's functions, looked up once when this module is imported: a forked child
must not load a library (another thread of its parent may have held the loader's lock when
it forked)."""
