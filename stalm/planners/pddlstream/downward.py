"""Fast Downward on the adaptive algorithm's optimistic problems, within a time limit.

One call translates and searches a problem over :data:`~.pddl_text.DOMAIN_PDDL` in a
temporary folder, and says where its time went and, without a plan, why (time or memory
limit, unsolvable, or no plan).
"""

from __future__ import annotations

import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from stalm.planners.pddlstream.pddl_text import DOMAIN_PDDL
from stalm.proposers.fast_downward import read_plan_steps, search_task, translate_task
from stalm.temp_folders import temporary_folder

SEARCH = "lazy_wastar([ff()], preferred=[ff()], w=2)"
"""Fast Downward's search: weighted A* (w = 2) with the FF heuristic and preferred operators;
costs matter (real values are cheaper than optimistic ones), so not plain greedy search."""


@dataclass(frozen=True)
class SearchResult:
    """One Fast Downward call: the plan (None if none was found) and where the time went."""

    steps: tuple[tuple[str, ...], ...] | None
    translate_s: float
    search_s: float
    reason: str = ""


def fast_downward(
    problem: str, search: str, time_limit_s: float, memory_limit_mb: int | None = None
) -> SearchResult:
    """Translate and search ``problem`` over :data:`DOMAIN_PDDL` within ``time_limit_s``
    (and ``memory_limit_mb`` for the search)."""
    with temporary_folder("pddlstream") as folder:
        work = Path(folder)
        (work / "domain.pddl").write_text(DOMAIN_PDDL)
        (work / "problem.pddl").write_text(problem)
        tick = time.monotonic()
        try:
            translate_task(work, max(time_limit_s, 0.1))
        except subprocess.TimeoutExpired:
            return SearchResult(None, time.monotonic() - tick, 0.0, "translator time limit")
        translated = time.monotonic()
        remaining = time_limit_s - (translated - tick)
        if remaining <= 0:
            return SearchResult(None, translated - tick, 0.0, "time limit")
        try:
            run = search_task(work, search, remaining, memory_limit_mb)
        except subprocess.TimeoutExpired:
            return SearchResult(
                None, translated - tick, time.monotonic() - translated, "search time limit"
            )
        searched = time.monotonic()
        if run.plan is None:
            output = run.output.lower()
            reason = "no plan"
            if "unsolvable" in output:
                reason = "unsolvable"
            elif "memory" in output:
                reason = "search memory limit"
            return SearchResult(None, translated - tick, searched - translated, reason)
        return SearchResult(read_plan_steps(run.plan), translated - tick, searched - translated)
