"""``stalm rerun``: run a trial again from its result record.

A record (``stalm solve --json``, or one line of an experiment's results file) keeps the
problem's name and hash (a solve's record also the problem itself, so that it reruns without
the file: :mod:`stalm.world.problem_record`), the planner, the seed and the whole resolved
settings tree. This command builds the same planner from them, solves the same problem with
the same seed and says whether the plan is the record's: with the same cached replies and a
run the clock did not cut short, it is, action for action; on the machine that made the record
number for number, on another one with its continuous values within
:data:`~stalm.geometry.tolerance.CONTINUOUS_TOLERANCE` (CPUs round the last bits of IK and
trigonometry differently), which still counts as the record's plan.

What a record names that reaches beyond the run -- the model's server, the reply-cache file --
is not taken from it: :mod:`stalm.cli.rerun_model` says what is used instead.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import typer

from stalm.cli.display import shown
from stalm.cli.paths import check_output_file
from stalm.cli.solve_output import console, note_embedded, out, solve_and_report
from stalm.errors import StalmError
from stalm.geometry.tolerance import CONTINUOUS_TOLERANCE, close_enough
from stalm.trial.records import read_record
from stalm.world.problem_record import RECORD_PROBLEM_HELP, record_problem

commands = typer.Typer()
"""The top-level commands this module adds; :mod:`stalm.cli.main` composes them."""


def first_difference(recorded: list[Any], now: list[Any]) -> int | None:
    """The index of the first action that differs between two plans (as JSON), or None: the
    discrete parts exactly, continuous values within the tolerance."""
    for index, (a, b) in enumerate(zip(recorded, now, strict=False)):
        if not close_enough(a, b):
            return index
    return None if len(recorded) == len(now) else min(len(recorded), len(now))


@commands.command("rerun")
def rerun_command(
    record_file: Annotated[
        Path,
        typer.Argument(
            help="A result of stalm solve --json, or an experiment's results (.jsonl) with --key."
        ),
    ],
    key: Annotated[
        str | None,
        typer.Option(help="The trial's key (or its start) in a JSON-lines results file."),
    ] = None,
    problem: Annotated[str | None, typer.Option(help=RECORD_PROBLEM_HELP)] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the new result as JSON.")
    ] = None,
    llm: Annotated[
        str | None,
        typer.Option(
            help="The model to ask (as stalm solve --llm; default $STALM_LLM). Without one, "
            "the record's model is not contacted: its replies come from the reply cache."
        ),
    ] = None,
    cache: Annotated[
        str | None,
        typer.Option(help="Reply cache mode: use (default), refresh, off or replay."),
    ] = None,
    cache_file: Annotated[
        Path | None,
        typer.Option(
            "--cache-file",
            help="The reply cache's SQLite file (default: replies.sqlite under "
            "$STALM_CACHE_DIR); a record's own is never used.",
        ),
    ] = None,
) -> None:
    """Run a recorded trial again and check that it gives the recorded plan.

    The problem, planner, seed and settings come from the record, but not the model nor the
    reply-cache file: the model is the one you name (--llm, $STALM_LLM), else the record's is
    replayed from the reply cache without contacting it. Exit 1 if the plan differs."""
    from stalm.cli.rerun_model import model_line, rerun_llm
    from stalm.planners.registry import asks_model, planner_entry, resolve
    from stalm.settings.io import from_mapping
    from stalm.trial.replay import read_plan

    if json_out is not None:
        check_output_file(json_out, "--json")
    record = read_record(record_file, key)
    if not isinstance(record.get("settings"), dict):
        raise StalmError(
            f"{record_file}: the record has no settings tree (it was written before records "
            "kept one), so it cannot be re-run from the record alone"
        )
    settings = from_mapping(record["settings"], f"{record_file}: settings")
    recorded_llm = settings.llm
    llm_section, model_source = rerun_llm(recorded_llm, llm, cache, cache_file)
    settings = replace(settings, llm=llm_section)
    entry = planner_entry(str(record.get("planner", "")))
    seed = record.get("seed")
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise StalmError(f"{record_file}: seed must be a non-negative integer, got {seed!r}")
    loaded = record_problem(record, str(record_file), problem, record_file.parent)
    try:  # the record's plan is read as replay and view read it: a forged one is refused here
        read_plan(loaded, record.get("plan") or [])
    except StalmError as error:
        raise StalmError(f"{record_file}: {error}") from None
    resolved = resolve(entry.name, settings, loaded)
    console.print(
        f"re-running {shown(loaded.name)} with {entry.name}, seed {seed}, from "
        f"{shown(record_file)}",
        highlight=False,
    )
    if asks_model(entry.name, resolved):
        line = model_line(resolved.llm, model_source, recorded_llm)
        console.print(shown(line), highlight=False, soft_wrap=True)
        if not resolved.llm.from_record:
            note_embedded(entry.name, resolved)
    result, fallback, _ = solve_and_report(entry.name, resolved, loaded, seed, json_out)
    now = json.loads(json.dumps(result.to_json()["plan"]))
    recorded = record.get("plan") or []
    differs = first_difference(recorded, now)
    if differs is None:
        exact = "" if recorded == now else f", continuous values within {CONTINUOUS_TOLERANCE:g}"
        out.print(
            f"[green]the plan is the record's ({len(now)} actions{exact})[/]", highlight=False
        )
    else:
        out.print(
            f"[red]the plan differs from the record's from action {differs + 1}[/] "
            f"(recorded {len(recorded)} actions, termination {shown(record.get('termination'))}"
            f"; now {len(now)}, {shown(result.termination)})",
            highlight=False,
        )
        if record.get("termination") in ("timeout", "error"):
            console.print(
                "[yellow]note:[/] the recorded run ended by "
                f"{shown(record.get('termination'))}: where the clock stops a run depends on "
                "the machine",
                highlight=False,
            )
    if fallback is not None:
        raise StalmError(f"--json {json_out} could not be written; the result is in {fallback}")
    if differs is not None:
        raise typer.Exit(1)
