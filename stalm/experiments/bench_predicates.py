"""Speed of the predicates: full computation vs Appendix A's cached update, per problem.

For each problem: the full computation for the initial state, then one feasible OPEN, PICK and
PLACE (found by sampling from a seeded generator), each timed as a cached update and as a
from-scratch computation of the same state.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.predicates.engine import PredicateEngine
from stalm.world.problem import load_problem
from stalm.world.state import State


def _feasible(
    domain: Domain, state: State, kind: type, rng: np.random.Generator
) -> tuple[DiscreteAction, State] | None:
    """A feasible action of ``kind`` from ``state`` (tries the legal ones in random order)."""
    legal = [a for a in domain.legal_actions(state) if isinstance(a, kind)]
    for index in rng.permutation(len(legal)):
        action = legal[int(index)]
        _, outcome = domain.sample_and_step(state, action, rng)
        if outcome.feasible:
            return action, outcome.state
    return None


def bench_problem(name: str, seed: int = 0) -> dict[str, object]:
    problem = load_problem(name)
    domain = Domain.create(problem)
    engine = PredicateEngine(problem, domain.sim, domain.base_planner)
    rng = np.random.default_rng(seed)
    state = problem.initial_state
    domain.base_planner.roadmap(frozenset(d.name for d in problem.spec.doors))
    start = time.perf_counter()
    cache = engine.compute(state)
    row: dict[str, object] = {
        "problem": name,
        "full_s": time.perf_counter() - start,
        "literals": len(cache.literals),
    }
    for label, kind in (("open", Open), ("pick", Pick), ("place", Place)):
        found = _feasible(domain, state, kind, rng)
        if found is None:
            continue
        action, nxt = found
        start = time.perf_counter()
        updated = engine.update(cache, action, nxt)
        update_s = time.perf_counter() - start
        start = time.perf_counter()
        scratch = engine.compute(nxt)
        full_s = time.perf_counter() - start
        row[label] = {
            "action": str(action),
            "update_s": update_s,
            "full_s": full_s,
            "speedup": full_s / update_s if update_s > 0 else float("inf"),
            "equal": updated.literals == scratch.literals,
        }
        cache, state = updated, nxt
    domain.close()
    return row


def run(
    names: list[str], seed: int, report: Callable[[dict[str, object]], None]
) -> list[dict[str, object]]:
    rows = []
    for name in names:
        row = bench_problem(name, seed)
        report(row)
        rows.append(row)
    return rows
