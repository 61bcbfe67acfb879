"""The shipped problem of meshes is solved by ``stalm solve`` with its defaults, the toy once
the two plates in front of it have moved, and its plan stands up under the physics check."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.domain.shipped_solves import assert_physics_passes, solve_and_replay


@pytest.mark.slow
def test_mesh1_is_solved_and_its_plan_passes_the_physics_check(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    solve = solve_and_replay(monkeypatch, tmp_path, "MESH1")
    words = list(solve.words)
    assert words.index("pick(plate_left)") < words.index("pick(toy)")
    assert words.index("pick(plate_right)") < words.index("pick(toy)")
    assert_physics_passes(solve)
