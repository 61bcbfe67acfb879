"""Comparing results across machines: discrete parts exactly, floats within the tolerance."""

from __future__ import annotations

import math

from stalm.geometry.tolerance import CONTINUOUS_TOLERANCE, close_enough, first_difference


def test_floats_within_the_tolerance_agree_and_beyond_it_differ_with_their_path() -> None:
    plan = {"plan": [{"action": ["pick", "salter"], "arm": [0.1, -0.2]}], "steps": 3}
    near = {"plan": [{"action": ["pick", "salter"], "arm": [0.1 + 1e-9, -0.2]}], "steps": 3}
    assert close_enough(plan, near)
    far = {"plan": [{"action": ["pick", "salter"], "arm": [0.1, -0.2 + 3e-6]}], "steps": 3}
    difference = first_difference(plan, far)
    assert difference is not None and difference.path == "/plan[0]/arm[1]"
    assert "expected -0.2" in str(difference)
    assert close_enough(plan, far, tolerance=1e-5)


def test_discrete_values_compare_exactly() -> None:
    assert first_difference(["pick", 3], ["pick", 4]) is not None  # counts
    assert first_difference({"a": True}, {"a": 1}) is not None  # a boolean is not a number
    assert first_difference({"a": None}, {"a": 0.0}) is not None
    assert first_difference("place", "pick") is not None
    assert close_enough(3, 3.0 + CONTINUOUS_TOLERANCE / 2)  # JSON keeps no int/float kind


def test_keys_lengths_and_special_floats() -> None:
    missing = first_difference({"a": 1, "b": 2}, {"a": 1})
    assert missing is not None and "keys missing: ['b']" in str(missing)
    assert close_enough({"a": 1, "b": 2}, {"b": 2, "a": 1})
    shorter = first_difference([1, 2, 3], [1, 2])
    assert shorter is not None and shorter.path == ".length"
    assert close_enough([math.nan], [math.nan])
    assert not close_enough([math.inf], [1e308])
    assert close_enough([-math.inf], [-math.inf])
