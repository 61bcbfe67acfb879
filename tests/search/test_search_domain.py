"""The search on the real PyBullet domain (P2): it runs unchanged on :class:`Domain`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.search import (
    ConcretizeResult,
    SearchResult,
    SearchSettings,
    SearchTree,
    TaskPlan,
    concretize,
    warm_started_uct,
)

pytestmark = pytest.mark.slow


def search_once(domain: Domain, seed: int) -> tuple[ConcretizeResult, SearchResult, dict[str, Any]]:
    problem = domain.problem
    rng = np.random.default_rng(seed)
    plans = [
        TaskPlan((Open("kitchen_door"), Pick("bottle2"), Place("bottle2", "on", "counter1"))),
        TaskPlan((Pick("salter"),)),  # the door is closed: no base path
        TaskPlan((Place("salter", "on", "table2"),)),  # nothing is held
    ]
    before = (domain.counters.samples, domain.counters.transitions)
    concrete = concretize(domain, problem.initial_state, plans, rng, horizon=problem.horizon)
    tree = SearchTree.for_root(domain, problem.initial_state)
    settings = SearchSettings(budget=3, horizon=6)
    result = warm_started_uct(
        domain, problem.initial_state, concrete.plans, rng, settings=settings, tree=tree
    )
    after = (domain.counters.samples, domain.counters.transitions)
    counted = (
        concrete.counts.samples + result.counters.samples,
        concrete.counts.transitions + result.counters.transitions,
    )
    assert counted == (after[0] - before[0], after[1] - before[1])
    return concrete, result, tree.snapshot(repr)


def test_concretize_and_search_on_p2(domain_factory: Callable[[str], Domain]) -> None:
    domain = domain_factory("P2")
    concrete, result, _ = search_once(domain, 0)
    assert concrete.failures == (
        (0, "partially_achieved_goal"),
        (1, "lack_of_3d_understanding"),
        (2, "precondition_violation"),
    )
    assert result.counters.warm_start_plans == 3
    assert result.counters.simulations == 3
    assert result.best_action is not None


def test_same_seed_same_search_on_p2(domain_factory: Callable[[str], Domain]) -> None:
    domain = domain_factory("P2")
    assert search_once(domain, 5) == search_once(domain, 5)
