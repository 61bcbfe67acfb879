"""The predicates on two cores (``predicates.workers``, beyond the paper).

:func:`stalm.predicates.forked.forked_map` deals items to forked copies of the process; the
engine's full computation with two workers must give what one process gives, literal for
literal and sample for sample, since every action draws from its own seeded generator.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.experiments.runner import check_cores
from stalm.experiments.trials import Arm, TrialSpec
from stalm.predicates import forked
from stalm.predicates.cache import PredicateCache
from stalm.predicates.deadline import DeadlinePassed
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.forked import forked_map
from stalm.predicates.samples import PredicateSettings
from stalm.settings.tree import RunSettings
from tests.cli_runner import run_cli

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(not forked.can_fork(), reason="no fork on this platform")


def test_results_come_back_in_the_items_order_for_any_number_of_workers() -> None:
    items = list(range(11))
    for workers in (1, 2, 3, 20):
        assert forked_map(lambda n: n * n, items, workers) == [n * n for n in items]
    assert forked_map(lambda n: n, [], 2) == []


def _slow_pid(_: object) -> int:
    time.sleep(0.2)  # long enough that a child forked meanwhile is dealt items too
    return os.getpid()


def test_items_are_shared_with_forked_processes() -> None:
    pids = forked_map(_slow_pid, list(range(6)), 2)
    assert os.getpid() in pids and len(set(pids)) == 2


def test_without_fork_everything_runs_here(monkeypatch) -> None:
    monkeypatch.setattr(forked, "can_fork", lambda: False)
    assert set(forked_map(_slow_pid, [0, 1, 2, 3], 2)) == {os.getpid()}


class _ItemFailed(Exception):
    pass


def _in_a_child(action):
    """A function that does ``action`` in a forked child and is slow in the caller."""
    caller = os.getpid()

    def function(item: int) -> int:
        if os.getpid() != caller:
            action()
        time.sleep(0.2)
        return item

    return function


def _fail() -> None:
    raise _ItemFailed("in a child")


def test_an_exception_in_a_child_is_raised_in_the_caller() -> None:
    with pytest.raises(_ItemFailed, match="in a child"):
        forked_map(_in_a_child(_fail), [0, 1, 2, 3], 2)


def test_an_exception_in_the_caller_is_raised_after_the_children_end() -> None:
    caller = os.getpid()

    def fail_here(item: int) -> int:
        if os.getpid() == caller:
            raise _ItemFailed("in the caller")
        time.sleep(0.2)  # a child is slow: the caller is dealt an item too
        return item

    with pytest.raises(_ItemFailed, match="in the caller"):
        forked_map(fail_here, [0, 1, 2, 3], 2)


def test_a_child_that_dies_without_answering_is_named() -> None:
    with pytest.raises(StalmError, match="ended without an answer: exit status 3 "):
        forked_map(_in_a_child(lambda: os._exit(3)), [0, 1, 2, 3], 2)


class _Unpicklable(Exception):
    def __init__(self, handle: object) -> None:
        super().__init__("cannot travel")
        self.handle = handle


def _raise_unpicklable() -> None:
    raise _Unpicklable(lambda: None)


def test_an_exception_that_does_not_pickle_still_says_what_it_was() -> None:
    with pytest.raises(RuntimeError, match="cannot travel"):
        forked_map(_in_a_child(_raise_unpicklable), [0, 1, 2, 3], 2)


def _samples(cache: PredicateCache) -> dict[tuple[object, ...], object]:
    """Every sample's pose and collisions, by its action."""
    found: dict[tuple[object, ...], object] = {
        ("base", name): motion.hits for name, motion in cache.base.items()
    }
    for name, record in cache.picks.items():
        found[("pick", name)] = (record.grasp, tuple(m.hits for m in record.motions))
    for kind, entries in (("place", cache.placements), ("beside", cache.targeted)):
        for key, samples in entries.items():
            found[(kind, *key)] = tuple((s.pose, s.motion.hits) for s in samples)
    return found


@pytest.mark.parametrize("name", ["P1", "P5"])
def test_two_workers_compute_what_one_does(domain_factory, name: str) -> None:
    domain = domain_factory(name)
    problem = domain.problem
    one, two = (
        PredicateEngine(
            problem, domain.sim, domain.base_planner, PredicateSettings(workers=workers)
        ).compute(problem.initial_state)
        for workers in (1, 2)
    )
    assert one.literals == two.literals
    assert one.targeted  # placements beside references were drawn (the third share)
    assert _samples(one) == _samples(two)


def test_workers_must_be_a_whole_number_of_processes() -> None:
    for bad in (0, -1, 1.5, True):
        with pytest.raises(StalmError, match=r"predicates\.workers"):
            PredicateSettings(workers=bad)  # type: ignore[arg-type]


def _spec(per_trial: int) -> TrialSpec:
    settings = RunSettings()
    settings = replace(settings, predicates=replace(settings.predicates, workers=per_trial))
    return TrialSpec("table2", Arm("stalm-symbolic", "stalm", settings), "P1", "", 0, 0, 300.0)


def test_an_experiment_refuses_more_predicate_processes_than_cores(monkeypatch) -> None:
    monkeypatch.setattr("stalm.experiments.runner.usable_cores", lambda: 2)
    check_cores([_spec(2)], 1)  # one trial, two processes: fits
    check_cores([_spec(1)], 2)  # two trials of one process each: fits
    with pytest.raises(StalmError, match=r"--workers 2 with predicates\.workers=2 .* 2 cores"):
        check_cores([_spec(1), _spec(2)], 2)


def test_a_deadline_passing_in_a_shared_computation_gives_it_up(domain_factory) -> None:
    domain = domain_factory("P3")  # its full computation takes over a second
    problem = domain.problem
    engine = PredicateEngine(problem, domain.sim, domain.base_planner, PredicateSettings(workers=2))
    start = time.monotonic()
    with pytest.raises(DeadlinePassed):
        engine.compute(problem.initial_state, deadline=lambda: time.monotonic() > start + 0.2)
    # nothing half-computed stays behind: the next computation is a whole one
    again = engine.compute(problem.initial_state)
    alone = PredicateEngine(problem, domain.sim, domain.base_planner, PredicateSettings())
    assert again.literals == alone.compute(problem.initial_state).literals


# --- A worker that dies, and signals around the fork (issue 46, item 8) -----------------------


def _children_die(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every forked child is killed (as the out-of-memory killer would) before its first item."""
    parent = os.getpid()
    work = forked._work

    def dying(function, items, dealer):
        if os.getpid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)
        return work(function, items, dealer)

    monkeypatch.setattr(forked, "_work", dying)


def test_a_killed_worker_is_one_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    _children_die(monkeypatch)
    with pytest.raises(StalmError) as caught:
        forked_map(abs, list(range(-8, 0)), 2)
    message = str(caught.value)
    assert re.fullmatch(
        r"a forked predicate worker \(pid \d+\) ended without an answer: killed by SIGKILL "
        r"\(killed, or out of memory\? predicates\.workers=1 computes without them\)",
        message,
    ), message


def test_a_killed_worker_ends_a_solve_with_one_line(monkeypatch, capsys) -> None:
    _children_die(monkeypatch)
    args = ["solve", "P2", "--proposer", "symbolic", "--time-budget", "30"]
    assert run_cli(monkeypatch, *args, "--set", "predicates.workers=2") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: a forked predicate worker (pid ")
    assert "killed by SIGKILL" in err[-1] and not any("Traceback" in line for line in err)


SIGNAL_AT_FORK = """
import os, signal, sys
from stalm.predicates.forked import forked_map
from stalm.stopping import Stopped, stop_message, stopping_on_signals

parent = os.getpid()
fork = os.fork

def fork_then_stop():  # a Ctrl-C or a group's TERM reaching the child as it is born
    pid = fork()
    if pid == 0:
        os.kill(os.getpid(), signal.SIGTERM)
    return pid

os.fork = fork_then_stop
who = lambda: "parent" if os.getpid() == parent else "child"
with stopping_on_signals():
    try:
        forked_map(abs, list(range(-8, 0)), 2)
        print(who(), "finished", flush=True)
    except Stopped as stop:
        print(who(), stop_message(stop), flush=True)
    except Exception as error:
        print(who(), type(error).__name__, error, flush=True)
"""


def _run_script(script: str) -> subprocess.CompletedProcess[str]:
    """``script`` run by a Python of its own, importing this checkout's stalm."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )


def test_a_stop_signal_at_the_fork_never_runs_the_callers_code_in_the_child() -> None:
    """A forked child given the parent's handlers would unwind through the parent's code
    with its :class:`~stalm.stopping.Stopped`: the command's "stopped by SIGTERM" printed
    twice, and the parent's temporary folders removed under it."""
    done = _run_script(SIGNAL_AT_FORK)
    lines = done.stdout.splitlines()
    assert len(lines) == 1, done.stdout + done.stderr
    assert lines[0].startswith("parent StalmError a forked predicate worker"), lines
    assert "killed by SIGTERM" in lines[0]


STOP_IN_AN_AT_FORK_HOOK = """
import logging  # as in stalm: it registers at-fork hooks, Python code run around a fork
import os, signal, threading, time
from stalm.predicates.forked import forked_map
from stalm.stopping import Stopped, stop_message, stopping_on_signals

threading.Thread(target=time.sleep, args=(60,), daemon=True).start()  # as numpy's, a model's
def stop_now():  # the forking thread holds TERM back: another thread takes it, in its time
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.2)
os.register_at_fork(before=stop_now)
with stopping_on_signals():
    try:
        forked_map(abs, list(range(-8, 0)), 2)
        print("finished: the stop was lost", flush=True)
    except Stopped as stop:
        print(stop_message(stop), flush=True)
"""


def test_a_stop_whose_handler_runs_in_an_at_fork_hook_is_not_lost() -> None:
    """os.fork runs Python's at-fork hooks; a TERM whose handler runs in one (held back in
    the forking thread, it reaches another thread) has its Stopped swallowed there, and the
    handler has made every later stop signal ignored. The stop is raised once the child is
    forked, and the child is waited for: the run stops as it would anywhere else."""
    done = _run_script(STOP_IN_AN_AT_FORK_HOOK)
    assert done.stdout == "stopped by SIGTERM\n", done.stdout + done.stderr
