"""The shipped problem of mugs and toys is solved by ``stalm solve`` with its defaults, the red
mug once the moulded toy in front of it has moved, and its plan stands up under the physics
check: the mugs and toys rest where the plan puts them, on the counter, shelf and table."""

from __future__ import annotations

from pathlib import Path

import pytest

from stalm.experiments.claim_check import initial_occluders
from stalm.world.problem import load_problem
from tests.domain.shipped_solves import assert_physics_passes, solve_and_replay


def test_the_red_mug_stands_behind_the_moulded_toy() -> None:
    assert initial_occluders(load_problem("MUG1")) == {"mug_red": frozenset({"moulded_toy"})}


@pytest.mark.slow
def test_mug1_is_solved_and_its_plan_passes_the_physics_check(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    solve = solve_and_replay(monkeypatch, tmp_path, "MUG1")
    words = list(solve.words)
    assert words.index("pick(moulded_toy)") < words.index("pick(mug_red)")
    assert "place(mug_red, on, shelf)" in words and "place(tall_toy, on, counter)" in words
    assert_physics_passes(solve)
