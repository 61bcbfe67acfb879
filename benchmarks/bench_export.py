"""How long does ``stalm export`` take to time a plan and write its trajectories?

``python benchmarks/bench_export.py [RESULT.json] [--rate 50] [--repeat 3]``

``RESULT.json`` is a record of ``stalm solve --json`` (by default the P5 record the tests use,
``tests/trial/data/p5_result.json``: 15 actions). Each run replays the plan in a fresh scene,
times every straight move with TOPP-RA (:func:`stalm.domain.schedule.schedule_plan`), samples
the trajectories and checks them against the limits (:func:`stalm.trial.export.trajectories_json`,
:func:`~stalm.trial.export.limit_violations`) and encodes the JSON; it prints the seconds of
each part, the moves, points, robot time and the file's size. toppra's import (about a second,
scipy and matplotlib) is paid once, before the first run, and printed apart. Numbers only;
nothing is asserted, because timings depend on the machine.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from stalm.domain.schedule import schedule_plan
from stalm.files import read_json_file
from stalm.trial.export import limit_violations, trajectories_json
from stalm.trial.replay import replay_result_json
from stalm.world.problem_record import record_problem
from stalm.world.robot_limits import panda_limits

P5_RECORD = Path(__file__).resolve().parents[1] / "tests" / "trial" / "data" / "p5_result.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("result", type=Path, nargs="?", default=P5_RECORD)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    data = read_json_file(args.result, "result file", finite=True)
    problem = record_problem(data, str(args.result), None, args.result.parent)
    tick = time.perf_counter()
    import toppra  # noqa: F401  (the import the first timed move would pay)

    print(f"import toppra: {time.perf_counter() - tick:.2f} s")
    limits = panda_limits()
    for attempt in range(args.repeat):
        tick = time.perf_counter()
        report = replay_result_json(problem, data)
        replayed = time.perf_counter()
        schedule = schedule_plan(report.actions, limits)
        timed = time.perf_counter()
        exported = trajectories_json(problem, schedule, args.rate)
        assert limit_violations(exported, limits) == []
        sampled = time.perf_counter()
        text = json.dumps(exported)
        done = time.perf_counter()
        moves = sum(len(t.base.moves) + len(t.arm.moves) for t in schedule.actions)
        points = sum(len(t["points"]) for t in exported["trajectories"])
        print(
            f"run {attempt + 1}: {problem.name}, {len(report.actions)} actions, {moves} moves: "
            f"replay {replayed - tick:.2f} s, TOPP-RA {timed - replayed:.2f} s "
            f"({1e3 * (timed - replayed) / moves:.1f} ms a move), sample and check "
            f"{sampled - timed:.2f} s, JSON {done - sampled:.2f} s; {points} points at "
            f"{args.rate:g} Hz, {schedule.duration:.1f} s of robot time, "
            f"{len(text) / 1e6:.1f} MB"
        )


if __name__ == "__main__":
    main()
