"""What the problems say of their geometry, where a user meets it:
``python benchmarks/problem_claims.py RESULTS.jsonl ...`` replays every solved record of the
experiment results named and prints, per problem, how many reached the goal and how many broke
a claim of :mod:`stalm.experiments.claim_check` (a goal object picked while an object that
occluded it at the start still stands in the way; an object carried to another room with every
door closed), each such step named. P5's and P6's grill trap is ``benchmarks/grill_trap.py``."""

from __future__ import annotations

import sys
from pathlib import Path

from stalm.experiments.claim_check import check_results

if __name__ == "__main__":
    results = [check_results(Path(arg)) for arg in sys.argv[1:]]
    checks = [c for result in results for c in result.checks]
    skipped = [why for result in results for why in result.skipped]
    print(
        "| problem | solved records replayed | goal reached | occluders named at the start "
        "| first picks checked | claim broken |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    for name in sorted({c.problem for c in checks}):
        mine = [c for c in checks if c.problem == name]
        broken = [c for c in mine if c.violations]
        occluders = "; ".join(
            f"{obj}: {', '.join(sorted(xs))}" for obj, xs in mine[0].occluders.items()
        )
        print(
            f"| {name} | {len(mine)} | {sum(c.reached_goal for c in mine)} | "
            f"{occluders or 'none'} | {sum(c.picks_checked for c in mine)} | {len(broken)} |"
        )
        for check in broken:
            print(f"  seed {check.seed}: " + "; ".join(check.violations))
    if skipped:
        print(f"\n{len(skipped)} solved records left out (not checked):")
        for why in skipped:
            print(f"  {why[:200]}")
