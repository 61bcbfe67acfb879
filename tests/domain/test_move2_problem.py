"""MOVE2 is non-monotonic, as its description says: the jar's goal (on the narrow shelf)
holds at the start and must be undone. The jar stands in front of the toy and the shelf has
room for it nowhere else, so every plan moves the jar off the shelf, the toy away, and the jar
back: the jar is placed twice. Checked on the scene (no other room on the shelf, the jar
occludes the toy) and where solves meet it: replayed solves of several seeds."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from stalm.domain.actions import Pick, Place
from stalm.experiments.claim_check import initial_occluders
from stalm.geometry.footprints import rotated_half_extent
from stalm.world.problem import load_problem
from stalm.world.relations import region_of
from tests.domain.shipped_solves import assert_physics_passes, solve_and_replay

SHELF = "narrow_shelf"


def test_the_jar_occludes_the_toy_and_fits_on_the_shelf_only_in_front_of_it() -> None:
    problem = load_problem("MOVE2")
    spec = problem.spec
    assert initial_occluders(problem) == {"toy": frozenset({"jar"})}
    shelf, jar, toy = spec.region(SHELF), spec.object("jar"), spec.object("toy")
    assert jar.on == toy.on == SHELF
    # the toy's footprint in the shelf's frame (u away from the robot, v to its left)
    toy_u, toy_v = rotated_half_extent(*toy.half_extents[:2], toy.yaw)
    toy_lo, toy_hi = toy.at[0] - toy_u, toy.at[0] + toy_u
    usable_u, usable_v = (size / 2 for size in shelf.usable_size)
    free = 0
    # every footprint of the jar on the shelf's usable area, every 5 degrees and 2 mm: those
    # clear of the toy's stand in front of it and in line with it
    for yaw in np.radians(np.arange(0.0, 90.0, 5.0)):
        half_u, half_v = rotated_half_extent(*jar.half_extents[:2], float(yaw))
        for u in np.arange(-usable_u + half_u, usable_u - half_u + 1e-9, 0.002):
            for v in np.arange(-usable_v + half_v, usable_v - half_v + 1e-9, 0.002):
                clear_u = u + half_u <= toy_lo or u - half_u >= toy_hi
                clear_v = abs(v - toy.at[1]) >= half_v + toy_v
                if clear_u or clear_v:
                    free += 1
                    assert u + half_u <= toy_lo and not clear_v, (math.degrees(yaw), u, v)
    assert free > 0  # it can stand where it starts, in front of the toy


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_solve_moves_the_jar_twice_and_passes_the_physics_check(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, seed: int
) -> None:
    solve = solve_and_replay(monkeypatch, tmp_path, "MOVE2", seed)
    spec, states = solve.problem.spec, solve.replay.states
    actions = [action.discrete for action in solve.replay.actions]
    # where the jar rests after each of its places (states[k + 1] follows actions[k])
    jar_places = [
        (k, region_of(spec, states[k + 1], "jar"))
        for k, action in enumerate(actions)
        if isinstance(action, Place) and action.obj == "jar"
    ]
    assert len(jar_places) >= 2, solve.words
    toy_pick = actions.index(Pick("toy"))
    # the toy is reached with the jar off the shelf; the jar comes back after the toy has gone
    assert region_of(spec, states[toy_pick], "jar") not in (None, SHELF), solve.words
    last, region = jar_places[-1]
    assert region == SHELF and last > toy_pick, solve.words
    assert_physics_passes(solve)
