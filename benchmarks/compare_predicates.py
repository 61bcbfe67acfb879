"""Two checkouts of stalm, the same predicate work, CPU seconds side by side.

``python benchmarks/compare_predicates.py OLD_DIR NEW_DIR [P1 ...]`` runs, per problem and in
a fresh process per checkout (interleaved, so both see the same machine load): the full
predicate computation of the initial state, then a six-step seeded random walk of feasible
sampled actions with Appendix A's cached update after each. It prints CPU seconds (wall time
on a shared machine says more about the other jobs than about the code) and whether the two
checkouts produced identical literals at every step: a speed change meant to keep behaviour
must show ``identical``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

WALK_STEPS = 6

CHILD = r"""
import json, sys, time
import numpy as np
from stalm.domain.mdp import Domain
from stalm.predicates.engine import PredicateEngine
from stalm.world.problem import load_problem

name, steps = sys.argv[1], int(sys.argv[2])
problem = load_problem(name)
domain = Domain.create(problem)
engine = PredicateEngine(problem, domain.sim, domain.base_planner)
domain.base_planner.roadmap(frozenset(d.name for d in problem.spec.doors))  # untimed
tick = time.process_time()
cache = engine.compute(problem.initial_state)
full = time.process_time() - tick
rng = np.random.default_rng(0)
state = problem.initial_state
trace = [sorted(map(str, cache.literals))]
tick = time.process_time()
for _ in range(steps):
    legal = domain.legal_actions(state)
    for index in rng.permutation(len(legal)):
        action = legal[int(index)]
        _, outcome = domain.sample_and_step(state, action, rng)
        if outcome.feasible:
            cache = engine.update(cache, action, outcome.state)
            state = outcome.state
            trace.append([str(action), sorted(map(str, cache.literals))])
            break
walk = time.process_time() - tick
print(json.dumps({"full_s": full, "walk_s": walk, "trace": trace}))
"""


def run(checkout: str, problem: str) -> dict[str, object]:
    env = {**os.environ, "PYTHONPATH": checkout}
    out = subprocess.run(
        [sys.executable, "-c", CHILD, problem, str(WALK_STEPS)],
        cwd=checkout,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    old, new, *names = sys.argv[1:]
    names = names or ["P1", "P2", "P3", "P4", "P5", "P6"]
    print("| problem | full: old / new (s) | ratio | walk: old / new (s) | ratio | literals |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name in names:
        before, after = run(old, name), run(new, name)
        same = "identical" if before["trace"] == after["trace"] else "DIFFERENT"
        fb, fa = float(before["full_s"]), float(after["full_s"])  # type: ignore[arg-type]
        wb, wa = float(before["walk_s"]), float(after["walk_s"])  # type: ignore[arg-type]
        print(
            f"| {name} | {fb:.1f} / {fa:.1f} | {fb / fa:.2f} | {wb:.1f} / {wa:.1f} | "
            f"{wb / wa:.2f} | {same} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
