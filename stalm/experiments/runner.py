"""Run an experiment's unfinished trials: in this process, in worker processes, or on Ray.

Whatever runs a trial, its record comes back here and is appended to the results log the
moment it arrives, so stopping the run (Ctrl-C, a kill, a lost cluster) loses only trials
that were still running. Workers are spawned, not forked: each builds its own PyBullet client
and model after start-up, and nothing of the caller's state leaks into them.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from typing import Any

from stalm.errors import StalmError
from stalm.experiments.results_log import ResultsLog
from stalm.experiments.trials import TrialSpec, run_trial

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
    if workers < 1:
        raise StalmError(f"--workers must be at least 1, got {workers}")
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


def _run_in_processes(todo: Sequence[TrialSpec], workers: int, keep: OnRecord) -> None:
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        queue = list(todo)
        running: dict[Future[dict[str, Any]], TrialSpec] = {}
        try:
            while queue or running:
                # submit only as many as can run, so a stop leaves the rest unstarted
                while queue and len(running) < workers:
                    spec = queue.pop(0)
                    running[pool.submit(run_trial, spec)] = spec
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in done:
                    running.pop(future)
                    keep(future.result())
        except BaseException:
            # stop now: running trials are lost (their records were never written)
            processes = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                process.terminate()
            raise
