"""Speed of the predicates: the batched engine beside its PyBullet reference, per problem.

For each problem, in one run on one machine: the initial state's full computation by the
batched engine (``full_s``), by the PyBullet reference (``reference_full_s``) and by the
batched engine limited to the relevant objects (``relevant_full_s``,
``predicates.relevant_only``); then one feasible OPEN, PICK and PLACE (found by sampling
from a seeded generator), each timed as a cached update by both engines. Every state's
literals are compared: ``literals_equal`` says the two engines agree on all of them, and
``missed`` counts the literals the reference has and the batched engine lacks (0, or the
batched engine is not conservative). With ``workers`` > 1 the full computation is also timed
shared among that many processes (``forked_full_s``, ``predicates.workers``), and
``forked_equal`` says its literals are the one process's. Wall times of this process
(``time.perf_counter``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.predicates.cache import PredicateCache
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.samples import PredicateSettings
from stalm.world.problem import load_problem, shipped_problems_dir
from stalm.world.state import State

BENCH_LAYOUTS = ("box1.yaml", "mesh1.yaml", "layouts/clutter35.yaml")
"""Problems beyond P1-P6 in the default list, under the package's problems folder: the scene
of boxes, the scene of meshes (whose pieces the batched engine covers with boxes) and the
35-object layout."""


def default_problems() -> list[str]:
    """P1..P6, the box and mesh scenes and the benchmark layout (by path)."""
    return [
        *("P1", "P2", "P3", "P4", "P5", "P6"),
        *(str(shipped_problems_dir() / layout) for layout in BENCH_LAYOUTS),
    ]


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


def _timed(compute: Callable[[], PredicateCache]) -> tuple[PredicateCache, float]:
    start = time.perf_counter()
    cache = compute()
    return cache, time.perf_counter() - start


def bench_problem(
    name: str, seed: int = 0, workers: int = 1, robot: str | None = None
) -> dict[str, object]:
    """One problem's row (see the module docstring), for ``robot`` if given."""
    problem = load_problem(name)
    if robot is not None:
        problem = problem.with_robot(robot)
    domain = Domain.create(problem)
    settings = PredicateSettings()
    batched, reference, relevant = (
        PredicateEngine(problem, domain.sim, domain.base_planner, config)
        for config in (
            replace(settings, engine="batched"),
            replace(settings, engine="pybullet"),
            replace(settings, engine="batched", relevant_only=True),
        )
    )
    rng = np.random.default_rng(seed)
    state = problem.initial_state
    domain.base_planner.roadmap(frozenset(d.name for d in problem.spec.doors))
    batched.compute(state)  # numba's compiled code loaded, roadmaps built: untimed
    cache, full_s = _timed(lambda: batched.compute(state))
    reference_cache, reference_full_s = _timed(lambda: reference.compute(state))
    relevant_cache, relevant_full_s = _timed(lambda: relevant.compute(state))
    missed = len(reference_cache.literals - cache.literals)
    equal = reference_cache.literals == cache.literals
    row: dict[str, object] = {
        "problem": problem.name if Path(name).suffix else name,
        "objects": len(problem.spec.objects),
        "full_s": full_s,
        "reference_full_s": reference_full_s,
        "relevant_full_s": relevant_full_s,
        "literals": len(cache.literals),
        "relevant_literals": len(relevant_cache.literals),
    }
    if workers > 1:
        forked = PredicateEngine(
            problem, domain.sim, domain.base_planner, replace(settings, workers=workers)
        )
        forked_cache, row["forked_full_s"] = _timed(lambda: forked.compute(state))
        row["forked_workers"] = workers
        row["forked_equal"] = forked_cache.literals == cache.literals
    for label, kind in (("open", Open), ("pick", Pick), ("place", Place)):
        found = _feasible(domain, state, kind, rng)
        if found is None:
            continue
        action, nxt = found
        updated, update_s = _timed(lambda: batched.update(cache, action, nxt))  # noqa: B023
        reference_updated, reference_update_s = _timed(
            lambda: reference.update(reference_cache, action, nxt)  # noqa: B023
        )
        scratch, scratch_s = _timed(lambda: batched.compute(nxt))  # noqa: B023
        missed += len(reference_updated.literals - updated.literals)
        equal = equal and reference_updated.literals == updated.literals
        row[label] = {
            "action": str(action),
            "update_s": update_s,
            "reference_update_s": reference_update_s,
            "full_s": scratch_s,
            "speedup": scratch_s / update_s if update_s > 0 else float("inf"),
            "equal": updated.literals == scratch.literals,
        }
        cache, reference_cache, state = updated, reference_updated, nxt
    row["literals_equal"] = equal
    row["missed"] = missed
    domain.close()
    return row


def run(
    names: list[str],
    seed: int,
    report: Callable[[dict[str, object]], None],
    workers: int = 1,
    robot: str | None = None,
) -> list[dict[str, object]]:
    rows = []
    for name in names:
        row = bench_problem(name, seed, workers, robot)
        report(row)
        rows.append(row)
    return rows
