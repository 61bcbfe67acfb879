"""``stalm bench ...``: speed figures reported as numbers (never asserted in tests)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from stalm.cli.display import shown
from stalm.cli.paths import check_output_file
from stalm.errors import StalmError
from stalm.files import write_replacing

bench_app = typer.Typer(
    help="Benchmarks: speed figures of the world, predicates, IK, LLM and search."
)
console = Console()


def _check(seed: int, json_out: Path | None, **counts: int) -> None:
    """Arguments a benchmark cannot run with, refused before it starts as one StalmError
    naming the option: a seed numpy refuses, a count below one (no targets: an IndexError; no
    attempts: an empty table), a ``--json`` that cannot be written (found only after the run,
    its figures lost)."""
    from stalm.trial.result import check_seed

    check_seed(seed, "--seed")
    for option, count in counts.items():
        if count < 1:
            raise StalmError(f"--{option} must be at least 1, got {count}")
    if json_out is not None:
        check_output_file(json_out, "--json")


def _write_rows(json_out: Path | None, rows: list[dict[str, object]]) -> None:
    """The rows as JSON at ``json_out`` (its folders made), all or nothing."""
    if json_out is not None:
        write_replacing(json_out, json.dumps(rows, indent=2))


@bench_app.command("world")
def bench_world(
    problems: Annotated[list[str] | None, typer.Argument(help="Problems (default P1..P6).")] = None,
    attempts: Annotated[
        int, typer.Option(help="Attempts per operator per problem (at least 1).")
    ] = 60,
    seed: Annotated[int, typer.Option(help="Seed of the random walk.")] = 0,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write the rows as JSON.")
    ] = None,
) -> None:
    """Median and p90 time of one PICK, PLACE and OPEN attempt; collision checks per second."""
    from stalm.experiments.bench_world import run

    _check(seed, json_out, attempts=attempts)
    names = problems or ["P1", "P2", "P3", "P4", "P5", "P6"]
    table = Table(title=f"one operator attempt ({attempts} per operator), ms")
    for column in (
        "problem",
        "PICK med/p90",
        "PLACE med/p90",
        "OPEN med/p90",
        "feasible P/P/O",
        "checks/s (ops)",
        "checks/s (raw)",
    ):
        table.add_column(column, justify="right")

    def fmt(summary: object) -> str:
        assert isinstance(summary, dict)
        if not summary.get("n"):
            return "-"
        return f"{summary['median_ms']:.1f} / {summary['p90_ms']:.1f}"

    def rate(summary: object) -> str:
        assert isinstance(summary, dict)
        return f"{summary.get('feasible_rate', 0.0):.2f}" if summary.get("n") else "-"

    rows = []
    with console.status("benchmarking...") as status:

        def report(row: dict[str, object]) -> None:
            status.update(f"done {shown(row['problem'])}")
            table.add_row(
                shown(row["problem"]),
                fmt(row["pick"]),
                fmt(row["place"]),
                fmt(row["open"]),
                f"{rate(row['pick'])}/{rate(row['place'])}/{rate(row['open'])}",
                f"{row['checks_per_second_in_operators']:.0f}",
                f"{row['raw_checks_per_second']:.0f}",
            )
            rows.append(row)

        run(names, attempts, seed, report, progress=lambda m: status.update(shown(m)))
    console.print(table)
    _write_rows(json_out, rows)


@bench_app.command("predicates")
def bench_predicates(
    problems: Annotated[
        list[str] | None,
        typer.Argument(
            help="Problems (default P1..P6, BOX1's boxes, MESH1's meshes and the 35-object "
            "benchmark layout)."
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed for the actions taken.")] = 0,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write the rows as JSON.")
    ] = None,
    workers: Annotated[
        int,
        typer.Option(
            help="Also time the full computation shared by this many processes (at most the "
            "cores this process may use)."
        ),
    ] = 1,
    robot: Annotated[
        str | None,
        typer.Option(
            "--robot",
            help="The robot (`stalm robot list`, or a robot file) in place of each problem's.",
        ),
    ] = None,
) -> None:
    """The batched predicate engine beside its PyBullet reference: the full computation, the
    relevance-limited one, and the cached updates after an OPEN, a PICK and a PLACE."""
    from stalm.cores import check_process_count
    from stalm.experiments.bench_predicates import default_problems, run

    _check(seed, json_out)
    check_process_count("--workers", workers)
    names = problems or default_problems()
    table = Table(title="predicates: batched engine / PyBullet reference (s)")
    for column in (
        "problem",
        "objects",
        "literals",
        "full",
        *([f"full, {workers} processes"] if workers > 1 else []),
        "relevant only",
        "OPEN update",
        "PICK update",
        "PLACE update",
        "same literals",
    ):
        table.add_column(column, justify="right")

    def ratio(new: object, reference: object) -> str:
        assert isinstance(new, float) and isinstance(reference, float)
        return f"{new:.3f} / {reference:.3f} = {reference / new:.1f}x" if new > 0 else "-"

    def cell(entry: object) -> str:
        if not isinstance(entry, dict):
            return "-"
        mark = "" if entry["equal"] else " (differs from scratch!)"
        return ratio(entry["update_s"], entry["reference_update_s"]) + mark

    def forked_cell(row: dict[str, object]) -> str:
        full, forked = row["full_s"], row["forked_full_s"]
        assert isinstance(full, float) and isinstance(forked, float)
        mark = "" if row["forked_equal"] else " (literals differ!)"
        return f"{forked:.3f} = {full / forked:.1f}x" + mark

    rows = []
    with console.status("benchmarking predicates...") as status:

        def report(row: dict[str, object]) -> None:
            status.update(f"done {shown(row['problem'])}")
            same = "yes" if row["literals_equal"] else f"no, {row['missed']} missed"
            table.add_row(
                shown(row["problem"]),
                str(row["objects"]),
                str(row["literals"]),
                ratio(row["full_s"], row["reference_full_s"]),
                *([forked_cell(row)] if workers > 1 else []),
                f"{row['relevant_full_s']:.2f} ({row['relevant_literals']} literals)",
                cell(row.get("open")),
                cell(row.get("pick")),
                cell(row.get("place")),
                same,
            )
            rows.append(row)

        run(names, seed, report, workers, robot)
    console.print(table)
    _write_rows(json_out, rows)


@bench_app.command("ik")
def bench_ik(
    problems: Annotated[
        list[str] | None, typer.Argument(help="Problems (default P1..P6; the Panda only).")
    ] = None,
    targets: Annotated[
        int, typer.Option(help="Reachable targets per problem or robot (at least 1).")
    ] = 200,
    seed: Annotated[int, typer.Option(help="Seed of the targets and the IK restarts.")] = 0,
    robot: Annotated[
        str,
        typer.Option(
            help="The arm: panda (on its mobile base, per problem), xarm6, iiwa, or a robot file."
        ),
    ] = "panda",
    attempts: Annotated[
        int, typer.Option(help="Seeds per target for an arm other than the Panda (at least 1).")
    ] = 20,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write the rows as JSON.")
    ] = None,
) -> None:
    """The compiled IK beside PyBullet's own on the same targets: time, reached, missed."""
    from stalm.world.robot_loader import load_robot

    _check(seed, json_out, targets=targets, attempts=attempts)
    load_robot(robot)  # a StalmError naming an unknown robot or a bad robot file
    if robot != "panda":
        if problems:
            raise StalmError(
                f"--robot {robot} is benchmarked fixed at the origin, without problems; "
                f"got {' '.join(problems)}"
            )
        _bench_arm(robot, targets, seed, attempts, json_out)
        return
    from stalm.experiments.bench_ik import run

    names = problems or ["P1", "P2", "P3", "P4", "P5", "P6"]
    table = Table(title="IK: compiled / PyBullet's (the reference)")
    for column in ("problem", "targets", "us per attempt", "reached", "missed"):
        table.add_column(column, justify="right")

    def report(row: dict[str, object]) -> None:
        new, old = row["attempt_s"], row["reference_attempt_s"]
        assert isinstance(new, float) and isinstance(old, float)
        table.add_row(
            shown(row["problem"]),
            str(row["targets"]),
            f"{new * 1e6:.0f} / {old * 1e6:.0f} = {old / new:.0f}x",
            f"{row['reached']} / {row['reference_reached']}",
            str(row["missed"]),
        )

    with console.status("benchmarking IK..."):
        rows = run(names, targets, seed, report)
    console.print(table)
    _write_rows(json_out, rows)


def _bench_arm(robot: str, targets: int, seed: int, attempts: int, json_out: Path | None) -> None:
    """``stalm bench ik --robot NAME`` for an arm other than the Panda: one row."""
    from stalm.experiments.bench_ik import bench_arm

    with console.status(f"benchmarking IK of {robot}..."):
        row = bench_arm(robot, targets, seed, attempts)
    table = Table(title=f"IK of {robot}, fixed: batched / PyBullet's (the reference)")
    for column in ("robot", "joints", "targets", "us per target", "reached", "missed"):
        table.add_column(column, justify="right")
    new, old = row["solve_s"], row["reference_solve_s"]
    assert isinstance(new, float) and isinstance(old, float)
    table.add_row(
        robot,
        str(row["joints"]),
        str(row["targets"]),
        f"{new * 1e6:.0f} / {old * 1e6:.0f} = {old / new:.0f}x",
        f"{row['reached']} / {row['reference_reached']}",
        str(row["missed"]),
    )
    console.print(table)
    _write_rows(json_out, [row])


@bench_app.command("search")
def bench_search(
    problems: Annotated[list[str] | None, typer.Argument(help="Problems (default P1..P6).")] = None,
    sims: Annotated[
        int, typer.Option(help="Simulations of plain UCT per problem (at least 1).")
    ] = 30,
    seed: Annotated[int, typer.Option(help="Seed of the search.")] = 0,
) -> None:
    """Simulations and T calls per second, and Concretize time for a 13-step plan."""
    from stalm.experiments.bench_search import bench_concretize, run

    _check(seed, None, sims=sims)
    names = problems or ["P1", "P2", "P3", "P4", "P5", "P6"]
    table = Table(title=f"plain UCT from the initial state, {sims} simulations")
    for column in ("problem", "seconds", "simulations/s", "T calls/s", "psi draws/s"):
        table.add_column(column, justify="right")
    with console.status("benchmarking the search...") as status:

        def report(row: dict[str, object]) -> None:
            status.update(f"done {shown(row['problem'])}")
            table.add_row(
                shown(row["problem"]),
                f"{row['seconds']:.1f}",
                f"{row['simulations_per_s']:.2f}",
                f"{row['transitions_per_s']:.1f}",
                f"{row['samples_per_s']:.1f}",
            )

        run(names, sims, seed, report)
        status.update("concretizing P1's 13-step plan")
        concrete = bench_concretize(seed)
    console.print(table)
    console.print(
        f"Concretize of a correct {concrete['plan_length']}-step plan (P1): median "
        f"{concrete['median_s']:.2f} s over {concrete['repeats']} runs, "
        f"{concrete['successes']} reached the goal"
    )
