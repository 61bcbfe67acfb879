"""Map a function over items in forked copies of this process: the predicates on two cores.

The samples of different actions are independent (each draws from a generator seeded by its
own key, :func:`~stalm.predicates.samples.stable_seed`), so the first computation of a
state's predicates can be split between processes. A forked child starts as an exact copy of
the caller -- its PyBullet scene, its compiled kernels, the state just set -- so nothing is
rebuilt or sent to it but the answer coming back, and what it computes is what the caller
would have computed (``tests/predicates/test_forked.py`` checks literal for literal and hit
for hit). Items are dealt one at a time to whichever process is free (the caller is one of
them), and the results are put back in the items' order, so who computed what changes
nothing.

Fork only: a platform without it (or ``workers`` <= 1) runs everything in the caller. The
child never returns into the caller's code: it sends its results (or the exception it met)
down a pipe and leaves with ``os._exit``, so no exit handler of the parent's runs twice.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from stalm import stopping
from stalm.errors import StalmError

Item = TypeVar("Item")
Result = TypeVar("Result")


def can_fork() -> bool:
    """Whether this platform can fork (Linux and macOS; not Windows)."""
    return "fork" in multiprocessing.get_all_start_methods()


def forked_map(
    function: Callable[[Item], Result], items: Sequence[Item], workers: int
) -> list[Result]:
    """``[function(item) for item in items]``, with up to ``workers`` processes (this one
    included). An exception in any process is raised here (this process's first); once one
    is met, or this process is interrupted, the others stop after the item they are on, and
    they are always waited for."""
    processes = min(workers, len(items)) if can_fork() else 1
    if processes <= 1:
        return [function(item) for item in items]
    dealer = _Dealer(len(items))  # shared by the children: made before they are forked
    children: list[tuple[int, int]] = []  # (pid, read end of its pipe)
    try:
        for _ in range(1, processes):
            children.append(_fork_child(function, items, dealer))
        answers = [_work(function, items, dealer)]
        while children:
            pid, read_end = children.pop(0)
            answers.append(_collect(pid, read_end))
    finally:
        dealer.stop()
        for pid, read_end in children:  # interrupted: leave no child behind
            os.close(read_end)
            os.waitpid(pid, 0)
    results: list[Result] = [None] * len(items)  # type: ignore[list-item]
    for answer in answers:
        if isinstance(answer, BaseException):
            raise answer
        for index, result in answer:
            results[index] = result
    return results


class _Dealer:
    """The next item's index, shared by forked processes: each takes one when it is free,
    so a process dealt cheap items takes more of them (the samples of one action may cost
    ten times another's)."""

    def __init__(self, count: int) -> None:
        self._count = count
        self._next = multiprocessing.get_context("fork").Value("q", 0)

    def take(self) -> int | None:
        with self._next.get_lock():
            index = int(self._next.value)
            if index >= self._count:
                return None
            self._next.value = index + 1
        return index

    def stop(self) -> None:
        """Deal nothing more."""
        with self._next.get_lock():
            self._next.value = self._count


def _work(
    function: Callable[[Item], Result], items: Sequence[Item], dealer: _Dealer
) -> list[tuple[int, Result]] | BaseException:
    """(index, result) of each item this process is dealt, or the exception it met (then
    nothing more is dealt to anyone)."""
    done: list[tuple[int, Result]] = []
    try:
        while (index := dealer.take()) is not None:
            done.append((index, function(items[index])))
    except Exception as error:
        dealer.stop()
        return error
    return done


def _fork_child(
    function: Callable[[Item], Result], items: Sequence[Item], dealer: _Dealer
) -> tuple[int, int]:
    """Fork a child that computes what it is dealt: its pid and the read end of its answer's
    pipe. The stop signals are held while it forks, so that none reaches the child before it
    has made them end it outright (:func:`_run_child`); a stop that reaches this process
    meanwhile is raised once the child is forked (or was not), and the child is waited for."""
    parent = os.getpid()
    read_end, write_end = os.pipe()
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, [])  # this thread's, unchanged
    pid = 0
    try:
        signal.pthread_sigmask(signal.SIG_BLOCK, stopping.STOP_SIGNALS)
        with stopping.stops_kept():  # a stop the at-fork hooks swallowed: raised after them
            pid = os.fork()
            if pid == 0:
                _run_child(function, items, dealer, (read_end, write_end), parent, mask)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # a stop held meanwhile arrives now
    except BaseException:  # no fork, or a stop: no child is left unwaited for
        os.close(read_end)
        os.close(write_end)
        if pid > 0:
            dealer.stop()
            os.waitpid(pid, 0)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        raise
    os.close(write_end)
    return pid, read_end


def _run_child(
    function: Callable[[Item], Result],
    items: Sequence[Item],
    dealer: _Dealer,
    pipe_ends: tuple[int, int],
    parent: int,
    mask: set[int | signal.Signals],
) -> None:
    """Compute what this child is dealt and send it; never returns (the child always exits).

    A stop signal (TERM, INT, HUP: a Ctrl-C reaches every process of the terminal's group)
    ends the child at once, as does its parent's death: with the parent's handlers it would
    unwind through the parent's code instead, print the parent's "stopped" line a second
    time and remove the parent's temporary folders on the way out."""
    status = 1
    try:
        for number in stopping.STOP_SIGNALS:
            if signal.getsignal(number) is not signal.SIG_IGN:
                signal.signal(number, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # held ones arrive now, and end it
        read_end, write_end = pipe_ends
        os.close(read_end)
        stopping.end_with_parent(signal.SIGKILL, parent)
        payload = _work(function, items, dealer)
        status = 0 if isinstance(payload, list) else 1
        try:
            data = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as error:  # an exception that does not pickle still says what it was
            data = pickle.dumps(RuntimeError(f"in a forked worker: {payload!r} ({error})"))
            status = 1
        with os.fdopen(write_end, "wb") as pipe:
            pipe.write(data)
    finally:
        os._exit(status)


def _collect(pid: int, read_end: int) -> list[tuple[int, Any]] | BaseException:
    """A child's answer, once it has exited."""
    try:
        with os.fdopen(read_end, "rb") as pipe:
            data = pipe.read()
    finally:
        _, status = os.waitpid(pid, 0)
    if not data:
        return StalmError(
            f"a forked predicate worker (pid {pid}) ended without an answer: {_ended(status)} "
            "(killed, or out of memory? predicates.workers=1 computes without them)"
        )
    answer: list[tuple[int, Any]] | BaseException = pickle.loads(data)
    return answer


def _ended(status: int) -> str:
    """How a child ended, from its wait status, in words."""
    code = os.waitstatus_to_exitcode(status)
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"
