"""Every golden case again with the last bits of continuous values moved (another CPU's bits).

Another machine rounds the last bits of IK, trigonometry and interpolation differently (see
``tests/golden.py`` and :mod:`stalm.geometry.tolerance`). Here :func:`nudged_floats` moves
every float those return by 1e-11 and each golden case of ``tests/test_behaviour_unchanged.py``
and ``tests/planners/test_planners_unchanged.py`` must still match its file: the same
decisions, literals, failures and terminations, continuous values within the tolerance. A
nudge beyond the tolerance must fail a golden comparison (the last tests), so the comparison
is not vacuous.

The cases that pay for a whole scene per problem run with ``pytest -m slow``; P2's run by
default.
"""

from __future__ import annotations

import pytest

from stalm.domain.mdp import Domain
from stalm.geometry.tolerance import CONTINUOUS_TOLERANCE
from stalm.predicates.engine import PredicateEngine
from stalm.world.problem import Problem
from tests.float_nudges import nudged_floats
from tests.golden import assert_matches, read
from tests.planners import test_planners_unchanged as planner_golden
from tests.test_behaviour_unchanged import (
    GOLDEN,
    PROBLEM_NAMES,
    draw_record,
    initial_record,
    stream_record,
    update_record,
)

NUDGE = 1e-11
"""About what a different CPU changes in an IK solution (7e-12 was seen)."""


def _slow_unless_p2(name: str) -> list[pytest.MarkDecorator]:
    return [] if name == "P2" else [pytest.mark.slow]


@pytest.fixture(scope="module")
def golden() -> dict:
    return read(GOLDEN)


@pytest.mark.parametrize("name", [pytest.param(n, marks=_slow_unless_p2(n)) for n in PROBLEM_NAMES])
def test_predicates_and_draws_hold_under_nudged_floats(
    golden: dict, problems: dict[str, Problem], name: str
) -> None:
    with nudged_floats(NUDGE) as nudger:
        domain = Domain.create(problems[name])
        try:
            engine = PredicateEngine(domain.problem, domain.sim, domain.base_planner)
            initial = engine.compute(domain.problem.initial_state)
            assert_matches(initial_record(initial), golden["initial"][name])
            assert_matches(draw_record(domain), golden["draws"][name])
            if name == "P2":
                assert_matches(update_record(domain, initial), golden["updates"])
        finally:
            domain.close()
    assert nudger.calls > 1000  # the nudges reached IK, the samplers and the interpolation


def test_streams_hold_under_nudged_floats(golden: dict, problems: dict[str, Problem]) -> None:
    with nudged_floats(NUDGE) as nudger:
        domain = Domain.create(problems["P2"])
        try:
            assert_matches(stream_record(domain), golden["streams"])
        finally:
            domain.close()
    assert nudger.calls > 0


@pytest.mark.parametrize(
    "case",
    [
        pytest.param(c, id=c.key, marks=[pytest.mark.slow] if c.slow else [])
        for c in planner_golden.CASES
    ],
)
def test_planner_cases_hold_under_nudged_floats(
    case: planner_golden.Case, problems: dict[str, Problem]
) -> None:
    expected = read(planner_golden.GOLDEN)[case.key]
    with nudged_floats(NUDGE) as nudger:
        assert_matches(planner_golden.run_case(case, problems[case.problem]), expected)
    assert nudger.calls > 0


def test_a_nudge_beyond_the_tolerance_fails_a_golden_case(
    golden: dict, problems: dict[str, Problem]
) -> None:
    """IK's solutions moved by 50 times the tolerance: P2's sampler draws no longer match."""
    with nudged_floats(50 * CONTINUOUS_TOLERANCE):
        domain = Domain.create(problems["P2"])
        try:
            rows = draw_record(domain)
        finally:
            domain.close()
    with pytest.raises(AssertionError, match="differs from the golden file at "):
        assert_matches(rows, golden["draws"]["P2"])


def test_a_planner_case_fails_on_a_value_changed_beyond_the_tolerance() -> None:
    """One arm joint of a golden plan moved by twice the tolerance is a difference; by half of
    it, none."""
    expected = read(planner_golden.GOLDEN)["uct[execution=best_q,sims=6]/P2/h2/s1"]
    waypoint = expected["plan"][0]["arm_waypoints"][2]
    for factor, differs in ((2.0, True), (0.5, False)):
        changed = read(planner_golden.GOLDEN)["uct[execution=best_q,sims=6]/P2/h2/s1"]
        changed["plan"][0]["arm_waypoints"][2][1] = waypoint[1] + factor * CONTINUOUS_TOLERANCE
        if differs:
            with pytest.raises(AssertionError, match=r"/plan\[0\]/arm_waypoints\[2\]\[1\]"):
                assert_matches(changed, expected)
        else:
            assert_matches(changed, expected)
