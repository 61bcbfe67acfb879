"""The symbolic proposer's scaling benchmark: crowded problems and Fast Downward's timings."""

from __future__ import annotations

import itertools
from pathlib import Path

import yaml

from stalm.experiments.bench_symbolic import KEEP_CLEAR, crowded_problem_data, time_downward


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
