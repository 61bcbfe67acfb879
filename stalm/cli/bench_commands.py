"""``stalm bench ...``: speed figures reported as numbers (never asserted in tests)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from stalm.cli.display import shown

bench_app = typer.Typer(help="Benchmarks: speed figures of the world, predicates, LLM and search.")
console = Console()


@bench_app.command("world")
def bench_world(
    problems: Annotated[list[str] | None, typer.Argument(help="Problems (default P1..P6).")] = None,
    attempts: Annotated[int, typer.Option(help="Attempts per operator per problem.")] = 60,
    seed: Annotated[int, typer.Option(help="Seed of the random walk.")] = 0,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write the rows as JSON.")
    ] = None,
) -> None:
    """Median and p90 time of one PICK, PLACE and OPEN attempt; collision checks per second."""
    from stalm.experiments.bench_world import run

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
    if json_out is not None:
        json_out.write_text(json.dumps(rows, indent=2))


@bench_app.command("predicates")
def bench_predicates(
    problems: Annotated[list[str] | None, typer.Argument(help="Problems (default P1..P6).")] = None,
    seed: Annotated[int, typer.Option(help="Seed for the actions taken.")] = 0,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write the rows as JSON.")
    ] = None,
) -> None:
    """Full predicate computation vs the cached update after an OPEN, a PICK and a PLACE."""
    from stalm.experiments.bench_predicates import run

    names = problems or ["P1", "P2", "P3", "P4", "P5", "P6"]
    table = Table(title="predicates: full computation and cached updates (s)")
    for column in (
        "problem",
        "literals",
        "full (s0)",
        "OPEN upd/full",
        "PICK upd/full",
        "PLACE upd/full",
    ):
        table.add_column(column, justify="right")

    def cell(entry: object) -> str:
        if not isinstance(entry, dict):
            return "-"
        mark = "" if entry["equal"] else " (differs!)"
        return f"{entry['update_s']:.3f} / {entry['full_s']:.2f} = {entry['speedup']:.0f}x{mark}"

    rows = []
    with console.status("benchmarking predicates...") as status:

        def report(row: dict[str, object]) -> None:
            status.update(f"done {shown(row['problem'])}")
            table.add_row(
                shown(row["problem"]),
                str(row["literals"]),
                f"{row['full_s']:.2f}",
                cell(row.get("open")),
                cell(row.get("pick")),
                cell(row.get("place")),
            )
            rows.append(row)

        run(names, seed, report)
    console.print(table)
    if json_out is not None:
        json_out.write_text(json.dumps(rows, indent=2))


@bench_app.command("search")
def bench_search(
    problems: Annotated[list[str] | None, typer.Argument(help="Problems (default P1..P6).")] = None,
    sims: Annotated[int, typer.Option(help="Simulations of plain UCT per problem.")] = 30,
    seed: Annotated[int, typer.Option(help="Seed of the search.")] = 0,
) -> None:
    """Simulations and T calls per second, and Concretize time for a 13-step plan."""
    from stalm.experiments.bench_search import bench_concretize, run

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
