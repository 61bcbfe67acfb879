"""A predicate computation stops at its deadline and keeps nothing (issue 16: budgets hold).

A full computation of P2's initial predicates takes seconds; a short trial must not wait for
it. The engine asks the deadline between samples and gives up with ``DeadlinePassed``.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from stalm.domain.actions import Pick
from stalm.domain.mdp import Domain
from stalm.predicates.deadline import DeadlinePassed
from stalm.predicates.engine import PredicateCache, PredicateEngine
from stalm.predicates.literals import GroundLiteral
from stalm.predicates.memo import PredicateMemo


class CountingDeadline:
    """A deadline double that passes at its ``passes_at``-th look (counting from 1)."""

    def __init__(self, passes_at: int) -> None:
        self.passes_at = passes_at
        self.looks = 0

    def __call__(self) -> bool:
        self.looks += 1
        return self.looks >= self.passes_at


@pytest.fixture(scope="module")
def p2(domain_factory) -> tuple[Domain, PredicateEngine]:
    domain = domain_factory("P2")
    # the roadmap the engine routes on (all doors open), built before anything is timed
    domain.base_planner.roadmap(frozenset(door.name for door in domain.problem.spec.doors))
    return domain, PredicateEngine(domain.problem, domain.sim, domain.base_planner)


def test_a_passed_deadline_stops_a_computation_at_its_first_look(p2) -> None:
    domain, engine = p2
    deadline = CountingDeadline(passes_at=1)
    tick = time.monotonic()
    with pytest.raises(DeadlinePassed):
        engine.compute(domain.problem.initial_state, deadline)
    assert deadline.looks == 1
    assert time.monotonic() - tick < 1.0


def test_the_engine_looks_between_samples_and_stops_at_the_first_look_past_the_deadline(
    p2,
) -> None:
    domain, engine = p2
    state = domain.problem.initial_state
    deadline = CountingDeadline(passes_at=6)
    with pytest.raises(DeadlinePassed):
        engine.compute(state, deadline)
    assert deadline.looks == 6, "it went on sampling after the deadline had passed"
    # the simulator is left as a finished computation leaves it: in the state asked about
    for name, pose in state.poses:
        (x, y, _), _ = domain.sim.object_pose(name)
        assert (x, y) == pytest.approx((pose.x, pose.y), abs=1e-6), name


def test_a_computation_ends_soon_after_a_wall_clock_deadline(p2) -> None:
    """A full computation takes over half a second (on the geometric core; seconds before
    it); a deadline a tenth of a second in stops it within one sample's time of it."""
    domain, engine = p2
    start = time.monotonic()
    with pytest.raises(DeadlinePassed):
        engine.compute(domain.problem.initial_state, lambda: time.monotonic() >= start + 0.1)
    assert time.monotonic() - start < 1.5


def test_a_cached_update_stops_at_its_deadline_and_leaves_its_cache(p2) -> None:
    domain, engine = p2
    state = domain.problem.initial_state
    # a cache with nothing sampled (a full one costs seconds): PICK's update resamples the
    # picked object's placements, each a sample the deadline is asked before
    cache = PredicateCache(state=state, literals=frozenset({GroundLiteral("HandAvailable")}))
    _, outcome = domain.sample_and_step(state, Pick("bottle1"), np.random.default_rng(3))
    assert outcome.feasible
    deadline = CountingDeadline(passes_at=1)
    with pytest.raises(DeadlinePassed):
        engine.update(cache, Pick("bottle1"), outcome.state, deadline)
    assert deadline.looks == 1
    assert cache.state == state and cache.literals == {GroundLiteral("HandAvailable")}
    assert cache.picks == {} and cache.placements == {} and cache.grasps == {}


def test_the_memo_keeps_nothing_of_a_computation_cut_short(p2) -> None:
    domain, engine = p2
    state = domain.problem.initial_state
    memo = PredicateMemo(engine, deadline=CountingDeadline(passes_at=3))
    with pytest.raises(DeadlinePassed):
        memo.of(state)
    assert memo.known(state) is None
    assert memo.computed_from_scratch == 0
    with pytest.raises(DeadlinePassed):  # asked again: computed again, not served half-done
        memo.of(state)
    assert memo.known(state) is None
