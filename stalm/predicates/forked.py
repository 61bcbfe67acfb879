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
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

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
            read_end, write_end = os.pipe()
            pid = os.fork()
            if pid == 0:  # the child: compute what it is dealt, send it, leave
                os.close(read_end)
                _run_child(function, items, dealer, write_end)
            os.close(write_end)
            children.append((pid, read_end))
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


def _run_child(
    function: Callable[[Item], Result], items: Sequence[Item], dealer: _Dealer, write_end: int
) -> None:
    """Compute what this child is dealt and send it; never returns (the child always exits)."""
    status = 1
    try:
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
        return RuntimeError(
            f"a forked predicate worker (pid {pid}) ended without an answer "
            f"(wait status {status}): killed, or out of memory?"
        )
    answer: list[tuple[int, Any]] | BaseException = pickle.loads(data)
    return answer
