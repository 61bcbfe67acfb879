"""Run an experiment's unfinished trials: in this process, in worker processes, or on Ray.

Whatever runs a trial, its record comes back here and is appended to the results log the
moment it arrives, so stopping the run (Ctrl-C, a kill, a lost cluster) loses only trials
that were still running. Workers are spawned, not forked: each builds its own PyBullet client
and model after start-up, and nothing of the caller's state leaks into them. A worker never
outlives the run: stopped by a signal, the run stops its workers; killed outright (``kill -9``,
the out-of-memory killer), each worker is sent TERM by the kernel and stops as it would have
been told to (:func:`~stalm.stopping.end_with_parent`).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from typing import Any

from stalm import stopping
from stalm.cores import check_process_count, usable_cores
from stalm.errors import StalmError
from stalm.experiments.results_log import ResultsLog
from stalm.experiments.trials import TrialSpec, run_trial
from stalm.temp_folders import remove_leftovers

OnRecord = Callable[[dict[str, Any]], None]


@dataclass(frozen=True)
class RunSummary:
    """What one invocation did: trials skipped as finished, run now, and solved now."""

    planned: int
    skipped: int
    ran: int
    solved: int
    errors: int


def pending_specs(specs: Sequence[TrialSpec], log: ResultsLog) -> list[TrialSpec]:
    """The specs whose trial has no finished record in ``log`` yet (duplicates dropped)."""
    finished = log.load().finished_keys()
    seen: set[str] = set()
    pending = []
    for spec in specs:
        if spec.key in finished or spec.key in seen:
            continue
        seen.add(spec.key)
        pending.append(spec)
    return pending


def run_experiment(
    specs: Sequence[TrialSpec],
    log: ResultsLog,
    *,
    workers: int = 1,
    ray_address: str | None = None,
    on_record: OnRecord | None = None,
) -> RunSummary:
    """Run every unfinished trial of ``specs`` and append its record to ``log``."""
    check_process_count("--workers", workers)
    if ray_address is None:
        check_cores(specs, workers)
    todo = pending_specs(specs, log)
    solved = errors = 0

    def keep(record: dict[str, Any]) -> None:
        nonlocal solved, errors
        log.append(record)
        solved += bool(record.get("success"))
        errors += record.get("termination") == "error"
        if on_record is not None:
            on_record(record)

    if ray_address is not None:
        from stalm.experiments.ray_runner import run_on_ray

        run_on_ray(todo, ray_address, keep)
    elif workers == 1:
        for spec in todo:
            keep(run_trial(spec))
    else:
        _run_in_processes(todo, workers, keep)
    return RunSummary(len(specs), len(specs) - len(todo), len(todo), solved, errors)


def check_cores(specs: Sequence[TrialSpec], workers: int) -> None:
    """Refuse trials side by side whose predicate processes (``predicates.workers``, each
    trial's own) would outnumber the cores: they would slow each other down, and a trial's
    time is what the experiment measures."""
    cores = usable_cores()
    for spec in specs:
        per_trial = spec.arm.config.predicates.workers
        if per_trial > 1 and workers * per_trial > cores:
            raise StalmError(
                f"--workers {workers} with predicates.workers={per_trial} ({spec.arm.label}) "
                f"would run {workers * per_trial} processes on {cores} cores: lower one of them"
            )


WORKER_STOP_S = 20.0
"""How long a stopped worker may take to clean up (kill its Fast Downward child, remove its
trial's folders) before it is killed."""


def _run_in_processes(todo: Sequence[TrialSpec], workers: int, keep: OnRecord) -> None:
    context = multiprocessing.get_context("spawn")
    # each worker stops on TERM, INT and HUP as this process does, cleaning up as it unwinds
    with ProcessPoolExecutor(
        max_workers=workers,
        mp_context=context,
        initializer=_start_worker,
        initargs=(os.getpid(),),
    ) as pool:
        queue = list(todo)
        running: dict[Future[dict[str, Any]], TrialSpec] = {}
        try:
            while queue or running:
                # submit only as many as can run, so a stop leaves the rest unstarted
                while queue and len(running) < workers:
                    spec = queue.pop(0)
                    running[pool.submit(run_trial_in_worker, spec)] = spec
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in done:
                    running.pop(future)
                    keep(future.result())
        except BaseException:
            # stop now: running trials are lost (their records were never written); each
            # worker is told to stop, and given the time to clean up before it is killed
            processes = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                process.terminate()
            for process in processes:
                process.join(WORKER_STOP_S)
                if process.is_alive():
                    process.kill()
                    process.join()
            raise


_in_trial = False
"""Whether this worker process is running a trial (see :class:`WorkerStopHandler`)."""


class WorkerStopHandler(stopping.StopHandler):
    """A worker stops on TERM, INT or HUP as the CLI does: inside a trial by unwinding it
    (:class:`~stalm.stopping.Stopped`, which cleans up its children and folders), while idle
    by ending at once (SystemExit, which multiprocessing ends a process with quietly)."""

    def stop(self, signum: int) -> None:
        if _in_trial:
            raise stopping.Stopped(signum)
        raise SystemExit(128 + signum)


def _start_worker(parent: int) -> None:
    """Stop on TERM, INT and HUP as the CLI does (:class:`WorkerStopHandler`), and on TERM
    when ``parent`` (the process that runs the experiment) ends, even by ``kill -9``: nothing
    else would end a worker waiting for its next trial, nor one in a trial nobody waits for
    (a KILL where TERM is ignored: it must not outlive its parent)."""
    handler = WorkerStopHandler()
    for number in stopping.STOP_SIGNALS:
        if signal.getsignal(number) is not signal.SIG_IGN:  # as stopping.install
            signal.signal(number, handler)
    handled = signal.getsignal(signal.SIGTERM) is handler
    stopping.end_with_parent(signal.SIGTERM if handled else signal.SIGKILL, parent)


def run_trial_in_worker(spec: TrialSpec) -> dict[str, Any]:
    """:func:`run_trial` in a pool's worker. A stop there has already cleaned up the trial
    when it arrives here; the worker then ends, rather than wait for a next trial."""
    global _in_trial
    _in_trial = True
    try:
        return run_trial(spec)
    except stopping.Stopped as stop:
        remove_leftovers(mine_too=True)  # one the signal cut off before its ``try``
        os._exit(stop.exit_code)
    finally:
        _in_trial = False
