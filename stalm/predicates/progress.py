"""How far a predicate computation is, told to whoever watches the trial (:mod:`stalm.progress`).

The engine's sampling loops report each item they finish; a report only listens, so what is
computed, and in which order, is the same with one or without."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TypeVar

from stalm.predicates.forked import forked_map

Report = Callable[[str, int, int], None]
"""Hears how far a computation is: a part (``picks``, ``placements``, ...), how many of its
items are done and of how many (0: not known in advance). It only listens: nothing it does
changes what is computed (:mod:`stalm.progress`)."""

Item = TypeVar("Item")
Result = TypeVar("Result")


def reported_map(
    function: Callable[[Item], Result],
    items: Sequence[Item],
    workers: int,
    report: Report | None,
    part: str,
) -> list[Result]:
    """:func:`forked_map` of ``function`` over ``items``, told to ``report`` item by item in
    one process; with forked workers (which cannot report to this process) only at the start
    and the end. The same calls in the same order either way."""
    if report is None:
        return forked_map(function, items, workers)
    total = len(items)
    report(part, 0, total)
    if workers > 1:
        results = forked_map(function, items, workers)
    else:
        results = []
        for item in items:
            results.append(function(item))
            report(part, len(results), total)
    report(part, total, total)
    return results
