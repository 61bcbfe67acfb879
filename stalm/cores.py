"""How many processes a run may start at once: never more than the cores it may use.

A count of processes -- a state's predicates shared among forked copies
(``predicates.workers``), trials side by side (``stalm experiment --workers``), the forked
predicates a benchmark times (``stalm bench predicates --workers``) -- past the cores only
makes the processes wait for each other: 1000 predicate workers on two cores spent six
times a trial's budget forking and swapping. :func:`check_process_count` refuses such a
count, and a count below one, with the same words wherever it is given.

The cores are those of this process's affinity (what ``taskset`` or a batch scheduler gives
it), not the machine's. Like :mod:`stalm.errors`, this module sits below every layer.
"""

from __future__ import annotations

import os

from stalm.errors import StalmError


def usable_cores() -> int:
    """The cores this process may run on (its affinity, as ``taskset`` sets it)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def check_process_count(name: str, value: object) -> int:
    """``value`` if it is a whole number of processes this process's cores can run at once,
    else a StalmError naming ``name`` (an option or a setting), the range and ``value``."""
    cores = usable_cores()
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= cores:
        raise StalmError(
            f"{name} must be a whole number of processes from 1 to {cores} (the cores this "
            f"process may use), got {value!r}"
        )
    return value
