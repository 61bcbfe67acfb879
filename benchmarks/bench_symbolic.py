"""Fast Downward's translate and search time against the number of objects (6, 12, 24):
``python benchmarks/bench_symbolic.py [SIZE ...]`` prints one JSON row per size and setting."""

from __future__ import annotations

import json
import sys

from stalm.experiments.bench_symbolic import run

if __name__ == "__main__":
    sizes = tuple(int(size) for size in sys.argv[1:]) or (6, 12, 24)
    run(sizes, report=lambda row: print(json.dumps(row), flush=True), progress=print)
