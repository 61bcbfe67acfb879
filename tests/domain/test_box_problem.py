"""The shipped problem of boxes is solved by ``stalm solve`` with its defaults, and its plan
stands up under the physics check: the boxes rest where the plan puts them."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.domain.shipped_solves import assert_physics_passes, solve_and_replay


@pytest.mark.slow
def test_box1_is_solved_and_its_plan_passes_the_physics_check(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    solve = solve_and_replay(monkeypatch, tmp_path, "BOX1")
    words = list(solve.words)
    # the can goes onto the ledge only after the crate has left it; the crackers move first
    assert words.index("pick(crate)") < words.index("place(can, on, ledge)")
    assert words.index("pick(crackers)") < words.index("pick(cereal)")
    assert_physics_passes(solve)
