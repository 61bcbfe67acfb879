"""Speed of the world: one PICK / PLACE / OPEN attempt and raw collision checks, per problem.

An *attempt* is one draw of κ with all its checks (base path, IK, arm sweep), i.e. a sampler
call with the operator's number of tries set to 1. States come from a seeded random walk of
feasible actions, so attempts include both feasible and infeasible draws, as a search makes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from stalm.domain.mdp import Domain
from stalm.domain.samplers import SamplerSettings
from stalm.world.problem import load_problem

ONE_TRY = SamplerSettings(pick_tries=1, place_tries=1, open_tries=1)


@dataclass
class OperatorTimes:
    seconds: list[float] = field(default_factory=list)
    feasible: int = 0

    def summary(self) -> dict[str, float]:
        if not self.seconds:
            return {"n": 0}
        ms = np.asarray(self.seconds) * 1000.0
        return {
            "n": len(ms),
            "median_ms": float(np.median(ms)),
            "p90_ms": float(np.percentile(ms, 90)),
            "feasible_rate": self.feasible / len(ms),
        }


def bench_problem(
    name: str, attempts: int = 60, seed: int = 0, progress: Callable[[str], None] | None = None
) -> dict[str, object]:
    """Time ``attempts`` attempts of each operator on problem ``name``; ``progress`` hears
    what is happening (the roadmaps come first and are not timed)."""
    say = progress or (lambda _message: None)
    problem = load_problem(name)
    domain = Domain.create(problem, sampler_settings=ONE_TRY)
    rng = np.random.default_rng(seed)
    domain.legal_actions(problem.initial_state)
    # warm the roadmaps (built once per scene, then cached on disk) outside the timings
    say(f"{name}: base roadmaps (built once per scene and door setting, then read from disk)")
    for doors in (frozenset(), frozenset(d.name for d in problem.spec.doors)):
        domain.base_planner.roadmap(doors)
    times = {"pick": OperatorTimes(), "place": OperatorTimes(), "open": OperatorTimes()}
    state = problem.initial_state
    checks_before = domain.sim.collision_checks
    wall_start = time.perf_counter()
    for _ in range(attempts * 6):
        if min(len(t.seconds) for k, t in times.items() if k != "open") >= attempts and len(
            times["open"].seconds
        ) >= min(attempts, 20):
            break
        legal = domain.legal_actions(state)
        action = legal[int(rng.integers(len(legal)))]
        kind = action.operator
        if kind == "open" and len(times["open"].seconds) >= attempts:
            continue
        done = sum(len(t.seconds) for t in times.values())
        say(f"{name}: operator attempts, {done} timed")
        start = time.perf_counter()
        _drawn, outcome = domain.sample_and_step(state, action, rng)
        times[kind].seconds.append(time.perf_counter() - start)
        if outcome.feasible:
            times[kind].feasible += 1
            if kind != "open" or rng.random() < 0.5:
                state = outcome.state
    elapsed = time.perf_counter() - wall_start
    checks = domain.sim.collision_checks - checks_before
    say(f"{name}: raw collision checks")
    raw = _raw_checks_per_second(domain)
    domain.close()
    return {
        "problem": name,
        "pick": times["pick"].summary(),
        "place": times["place"].summary(),
        "open": times["open"].summary(),
        "checks_per_second_in_operators": checks / elapsed if elapsed > 0 else 0.0,
        "raw_checks_per_second": raw,
    }


def _raw_checks_per_second(domain: Domain, n: int = 2000) -> float:
    """Whole-world contact queries per second with the robot at its start."""
    domain.sim.set_state(domain.problem.initial_state)
    start = time.perf_counter()
    for _ in range(n):
        domain.sim.robot_contacts()
    return n / (time.perf_counter() - start)


def run(
    names: list[str],
    attempts: int,
    seed: int,
    report: Callable[[dict[str, object]], None],
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, object]]:
    rows = []
    for name in names:
        row = bench_problem(name, attempts, seed, progress)
        report(row)
        rows.append(row)
    return rows
