"""Trials on a Ray cluster (``stalm experiment ... --ray ADDRESS``; needs ``stalm[ray]``).

Each trial is one Ray task with one CPU. The caller's reply cache goes out once as an object
in Ray's store; a task runs on a private copy of it, and hands back the copy when the model
was asked something new, which the caller merges into its own cache. So replies made on the
cluster are reusable (and replayable) at home, and records arrive here one by one, appended to
the caller's results log as they come, exactly as with local workers. Every worker node needs
the same stalm installed; the problem files travel inside the trial specs.

``ADDRESS`` is what ``ray.init`` takes (``auto``, ``ray://head:10001``), or ``local`` to start
a private single-machine instance for this run.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from stalm.errors import StalmError
from stalm.experiments.trials import TrialSpec, run_trial
from stalm.llm.cache_file import ReplyCache
from stalm.temp_folders import temporary_folder

RemoteResult = tuple[dict[str, Any], bytes | None]


def trial_with_cache_copy(spec: TrialSpec, cache_bytes: bytes) -> RemoteResult:
    """Run ``spec`` against a private copy of the caller's reply cache; return its record and
    the copy if the trial added replies to it (else None)."""
    with temporary_folder("ray") as folder:
        path = Path(folder) / "replies.sqlite"
        path.write_bytes(cache_bytes)
        before = len(ReplyCache(path))
        settings = spec.arm.config
        llm = dataclasses.replace(settings.llm, cache_file=str(path))
        config = dataclasses.replace(settings, llm=llm)
        local = dataclasses.replace(spec, arm=dataclasses.replace(spec.arm, config=config))
        record = run_trial(local)
        if "settings" in record:  # the copy is gone after this task: record the caller's file
            record["settings"]["llm"]["cache_file"] = settings.llm.cache_file
        cache = ReplyCache(path)
        if len(cache) == before:
            return record, None
        export = Path(folder) / "export.sqlite"
        cache.export(export)  # one consistent file, write-ahead log folded in
        return record, export.read_bytes()


def _cache_snapshot(cache: ReplyCache) -> bytes:
    with temporary_folder("ray") as folder:
        return cache.export(Path(folder) / "snapshot.sqlite").read_bytes()


def merge_cache_bytes(cache: ReplyCache, data: bytes) -> int:
    """Merge a cache file's bytes (from a worker) into ``cache``; return the replies added."""
    with temporary_folder("ray") as folder:
        path = Path(folder) / "incoming.sqlite"
        path.write_bytes(data)
        return cache.merge_from(path)


def run_on_ray(
    todo: Sequence[TrialSpec],
    address: str,
    keep: Callable[[dict[str, Any]], None],
    cache: ReplyCache | None = None,
) -> None:
    """Run ``todo`` as Ray tasks and ``keep`` each record as it arrives."""
    try:
        import ray
    except ImportError:
        raise StalmError("--ray needs Ray: pip install 'stalm[ray]'") from None
    if not todo:
        return
    started_here = not ray.is_initialized()
    if started_here:
        try:
            ray.init(
                address=None if address == "local" else address,
                include_dashboard=False,
                log_to_driver=False,
            )
        except (ConnectionError, RuntimeError, ValueError) as error:
            raise StalmError(f"cannot reach the Ray cluster at {address!r}: {error}") from error
    if cache is None:  # replay only reads: a cache nobody may write still replays
        replay = all(spec.arm.config.llm.cache == "replay" for spec in todo)
        cache = ReplyCache(read_only=replay)
    try:
        snapshot = ray.put(_cache_snapshot(cache))
        remote = ray.remote(num_cpus=1, max_retries=0)(trial_with_cache_copy)
        pending = [remote.remote(spec, snapshot) for spec in todo]
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                try:
                    record, new_cache = ray.get(done[0])
                except ray.exceptions.RayTaskError as error:
                    cause = getattr(error, "cause", None)
                    if isinstance(cause, StalmError):
                        raise StalmError(str(cause)) from None
                    raise
                if new_cache is not None:
                    merge_cache_bytes(cache, new_cache)
                keep(record)
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise
    finally:
        if started_here:
            ray.shutdown()
