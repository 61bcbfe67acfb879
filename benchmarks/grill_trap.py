"""The grill trap where a user meets it: ``python benchmarks/grill_trap.py RESULTS.jsonl ...``
replays every solved P5 and P6 record of the experiment results named and prints, per problem,
how many reached the goal, how many put the grill last, and how many put anything on the
walled counter while the grill stood on it (each such step named); then the trap's fidelity
(paper §4.4, Figure 5): of the task plans in each trial's first proposal, how many put the
grill on its counter before another object, and how many of those Concretize found
infeasible."""

from __future__ import annotations

import sys
from pathlib import Path

from stalm.experiments.results_log import read_records
from stalm.experiments.trap_check import check_results, first_proposal, same_version
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

    print()
    print(
        "| problem | trials with a step log | first-proposal plans | grill first "
        "| of those infeasible |"
    )
    print("| --- | --- | --- | --- | --- |")
    for name, problem in problems.items():
        firsts = [
            found
            for arg in sys.argv[1:]
            for record in read_records(Path(arg)).latest_by_key().values()
            if record.get("problem") == name
            and same_version(problem, record)
            and (found := first_proposal(problem, record)) is not None
        ]
        plans = sum(f.plans for f in firsts)
        first = sum(f.grill_first for f in firsts)
        failed = sum(f.grill_first_failed for f in firsts)
        print(f"| {name} | {len(firsts)} | {plans} | {first} | {failed} |")
