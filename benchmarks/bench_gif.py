"""How long does ``--gif`` take to render and write a plan's animation?

``python benchmarks/bench_gif.py RESULT.json [--size 240] [--repeat 1] [--out FILE]``

``RESULT.json`` is a record of ``stalm solve --json`` (e.g. ``stalm solve P2 --seed 0 --json
p2.json``); its plan is replayed in a fresh scene and animated exactly as ``stalm solve --gif``
does (:func:`stalm.viz.animate.write_animation`). It prints the frames, the seconds spent
rendering them and writing the GIF, and the file's size. Numbers only; nothing is asserted,
because timings depend on the machine.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from stalm.trial.replay import replay_result_json
from stalm.viz.animate import write_animation
from stalm.world.problem import load_problem
from stalm.world.scene import Sim


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("result", type=Path)
    parser.add_argument("--size", type=int, default=240)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    data = json.loads(args.result.read_text(encoding="utf-8"))
    problem = load_problem(str(data["problem"]))
    report = replay_result_json(problem, data)
    pairs = list(zip(report.actions, report.states[1:], strict=False))
    out = args.out or Path(tempfile.mkdtemp()) / "plan.gif"
    for attempt in range(args.repeat):
        with Sim(problem.spec) as sim:
            tick = time.perf_counter()
            frames = write_animation(sim, report.states[0], pairs, out, size=args.size)
            seconds = time.perf_counter() - tick
        print(
            f"run {attempt + 1}: {frames} frames at {2 * args.size}x{args.size} in "
            f"{seconds:.2f} s ({out.stat().st_size / 1e3:.0f} kB)"
        )


if __name__ == "__main__":
    main()
