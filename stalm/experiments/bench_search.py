"""Speed of the search: simulations and T calls per second, and Concretize of a 13-step plan.

Plain UCT (no warm start) runs from each problem's initial state for a fixed number of
simulations; Concretize grounds P1's 13-step plan (open the door, then move each of the six
objects to its goal), the length of the paper's longer plans.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.search import SearchSettings, TaskPlan, concretize, warm_started_uct
from stalm.world.problem import load_problem

P1_PLAN: tuple[DiscreteAction, ...] = (
    Open("kitchen_door"),
    Pick("bottle3"),
    Place("bottle3", "on", "table1"),
    Pick("bottle1"),
    Place("bottle1", "on", "table1"),
    Pick("salter3"),
    Place("salter3", "on", "table2"),
    Pick("salter1"),
    Place("salter1", "on", "counter2"),
    Pick("bottle2"),
    Place("bottle2", "on", "counter2"),
    Pick("salter2"),
    Place("salter2", "on", "shelf_lower"),
)


def bench_uct(name: str, simulations: int, seed: int) -> dict[str, object]:
    problem = load_problem(name)
    domain = Domain.create(problem)
    for doors in (frozenset(), frozenset(d.name for d in problem.spec.doors)):
        domain.base_planner.roadmap(doors)
    rng = np.random.default_rng(seed)
    start = time.perf_counter()
    result = warm_started_uct(
        domain, problem.initial_state, (), rng, settings=SearchSettings(budget=simulations)
    )
    elapsed = time.perf_counter() - start
    domain.close()
    return {
        "problem": name,
        "simulations": result.counters.simulations,
        "seconds": elapsed,
        "simulations_per_s": result.counters.simulations / elapsed,
        "transitions_per_s": result.counters.transitions / elapsed,
        "samples_per_s": result.counters.samples / elapsed,
        "reached_goal": result.success,
    }


def bench_concretize(seed: int, repeats: int = 3) -> dict[str, object]:
    problem = load_problem("P1")
    domain = Domain.create(problem)
    for doors in (frozenset(), frozenset(d.name for d in problem.spec.doors)):
        domain.base_planner.roadmap(doors)
    times, successes = [], 0
    for index in range(repeats):
        rng = np.random.default_rng(seed + index)
        start = time.perf_counter()
        result = concretize(domain, problem.initial_state, [TaskPlan(P1_PLAN)], rng)
        times.append(time.perf_counter() - start)
        successes += result.success
    domain.close()
    return {
        "plan_length": len(P1_PLAN),
        "median_s": float(np.median(times)),
        "successes": successes,
        "repeats": repeats,
    }


def run(
    names: list[str], simulations: int, seed: int, report: Callable[[dict[str, object]], None]
) -> list[dict[str, object]]:
    rows = []
    for name in names:
        row = bench_uct(name, simulations, seed)
        report(row)
        rows.append(row)
    return rows
