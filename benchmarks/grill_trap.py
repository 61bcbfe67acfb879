"""The grill trap where a user meets it: ``python benchmarks/grill_trap.py RESULTS.jsonl ...``
replays every solved P5 and P6 record of the experiment results named and prints, per problem,
how many reached the goal, how many put the grill last, and how many put anything on the
walled counter while the grill stood on it (each such step named)."""

from __future__ import annotations

import sys
from pathlib import Path

from stalm.experiments.trap_check import check_results
from stalm.world.problem import load_problem

if __name__ == "__main__":
    problems = {name: load_problem(name) for name in ("P5", "P6")}
    checks = [c for arg in sys.argv[1:] for c in check_results(Path(arg), problems)]
    print("| problem | solved records replayed | goal reached | grill last | trap broken |")
    print("| --- | --- | --- | --- | --- |")
    for name in problems:
        mine = [c for c in checks if c.problem == name]
        broken = [c for c in mine if c.violations]
        print(
            f"| {name} | {len(mine)} | {sum(c.reached_goal for c in mine)} | "
            f"{sum(c.grill_last for c in mine)} | {len(broken)} |"
        )
        for check in broken:
            print(f"  seed {check.seed}: " + "; ".join(check.violations))
