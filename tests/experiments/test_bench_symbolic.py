"""The symbolic proposer's scaling benchmark: crowded problems and Fast Downward's timings."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest
import yaml

from stalm.experiments.bench_symbolic import KEEP_CLEAR, crowded_problem_data, run, time_downward


def test_crowded_problems_add_cans_beside_the_goal_on_the_free_regions(problems) -> None:
    base = yaml.safe_load(Path(problems["P2"].source).read_text(encoding="utf-8"))
    data = crowded_problem_data(base, 24)
    objects = data["objects"]
    assert len(objects) == 24 and len({o["name"] for o in objects}) == 24
    assert objects[:4] == base["objects"] and data["goal"] == base["goal"]
    added = objects[4:]
    assert "counter2" not in {o["on"] for o in added}  # the salter's region stays as in P2
    assert len({o["on"] for o in added}) == 6  # spread over every other region
    for a, b in itertools.combinations(objects, 2):
        if a["on"] == b["on"] and b in added:  # P2's own objects stand as they stood
            (xa, ya), (xb, yb) = a["at"], b["at"]
            assert (xa - xb) ** 2 + (ya - yb) ** 2 >= KEEP_CLEAR**2 - 1e-9, (a, b)


def test_fast_downward_is_timed_on_a_problems_predicates(problems, initial_literals) -> None:
    row = time_downward(problems["P2"], initial_literals("P2"), True, plans=1)
    assert isinstance(row["translate_s"], float) and row["translate_s"] > 0
    assert isinstance(row["operators"], int) and row["operators"] > 0
    assert row["plan_lengths"] and row["plan_lengths"][0] >= 7  # P2's optimal length is 7


@pytest.mark.slow
def test_the_benchmark_reports_both_groundings_per_size() -> None:
    rows: list[dict[str, object]] = []
    said: list[str] = []
    run((5,), report=rows.append, progress=said.append)
    assert [row["goal_relations_only"] for row in rows] == [True, False]
    assert all(row["objects"] == 5 and row["problem"] == "P2_5" for row in rows)
    goal_only, every_pair = (row["operators"] for row in rows)
    assert isinstance(goal_only, int) and isinstance(every_pair, int)
    assert goal_only < every_pair  # what grounding only the goal's relations buys
    assert said[0] == "P2_5: predicates of the initial state (untimed)"
