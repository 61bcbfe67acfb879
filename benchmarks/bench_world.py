"""Run the world benchmark without the CLI: ``python benchmarks/bench_world.py [P1 ...]``."""

from __future__ import annotations

import json
import sys

from stalm.experiments.bench_world import run

if __name__ == "__main__":
    names = sys.argv[1:] or ["P1", "P2", "P3", "P4", "P5", "P6"]
    run(names, attempts=60, seed=0, report=lambda row: print(json.dumps(row)))
