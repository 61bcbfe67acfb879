"""Map a function over items in forked copies of this process: the predicates on two cores.

The samples of different actions are independent (each draws from a generator seeded by its
own key, :func:`~stalm.predicates.samples.stable_seed`), so the first computation of a
state's predicates can be split between processes. A forked child starts as an exact copy of
the caller -- its PyBullet scene, its compiled kernels, the state just set -- so nothing is
rebuilt or sent to it but the answer coming back, and what it computes is what the caller
would have computed (``tests/predicates/test_forked.py`` checks literal for literal and hit
for hit). Items are dealt round-robin: share ``k`` holds items ``k, k + n, ...``; the caller
computes share 0 itself while the children compute the rest.

Fork only: a platform without it (or ``workers`` <= 1) runs everything in the caller. The
child never returns into the caller's code: it sends its results (or the exception it met)
down a pipe and leaves with ``os._exit``, so no exit handler of the parent's runs twice.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
from collections.abc import Callable, Sequence
from typing import TypeVar

Item = TypeVar("Item")
Result = TypeVar("Result")


def can_fork() -> bool:
    """Whether this platform can fork (Linux and macOS; not Windows)."""
    return "fork" in multiprocessing.get_all_start_methods()


def forked_map(
    function: Callable[[Item], Result], items: Sequence[Item], workers: int
) -> list[Result]:
    """``[function(item) for item in items]``, with up to ``workers`` processes (this one
    included). An exception in any share is raised here, the first share's first; the
    children are always waited for."""
    shares = min(workers, len(items)) if can_fork() else 1
    if shares <= 1:
        return [function(item) for item in items]
    children: list[tuple[int, int]] = []  # (pid, read end of its pipe)
    try:
        for share in range(1, shares):
            read_end, write_end = os.pipe()
            pid = os.fork()
            if pid == 0:  # the child: compute its share, send it, leave
                os.close(read_end)
                _run_child(function, items[share::shares], write_end)
            os.close(write_end)
            children.append((pid, read_end))
        own: list[Result] | BaseException
        try:
            own = [function(item) for item in items[0::shares]]
        except Exception as error:  # collect the children before raising
            own = error
        answers: list[list[Result] | BaseException] = [own]
        while children:
            pid, read_end = children.pop(0)
            answers.append(_collect(pid, read_end))  # type: ignore[arg-type]
    finally:
        for pid, read_end in children:  # a fork failed part way: leave no child behind
            os.close(read_end)
            os.waitpid(pid, 0)
    for answer in answers:
        if isinstance(answer, BaseException):
            raise answer
    results: list[Result] = [None] * len(items)  # type: ignore[list-item]
    for share, answer in enumerate(answers):
        results[share::shares] = answer  # type: ignore[assignment]
    return results


def _run_child(function: Callable[[Item], Result], share: Sequence[Item], write_end: int) -> None:
    """Compute ``share`` and send it; never returns (whatever happens, the child exits)."""
    status = 1
    try:
        payload: list[Result] | BaseException
        try:
            payload = [function(item) for item in share]
            status = 0
        except BaseException as error:  # every failure goes back to the caller
            payload = error
        try:
            data = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as error:  # an exception that does not pickle still says what it was
            data = pickle.dumps(RuntimeError(f"in a forked worker: {payload!r} ({error})"))
            status = 1
        with os.fdopen(write_end, "wb") as pipe:
            pipe.write(data)
    finally:
        os._exit(status)


def _collect(pid: int, read_end: int) -> list[object] | BaseException:
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
    answer: list[object] | BaseException = pickle.loads(data)
    return answer
