"""``stalm same-plans``: did a change alter what the planners do?

Run the same experiment (the same master seed, trials and settings) before and after a change,
then compare the two results logs: the table says per planner row and problem how many trials
executed the same plan, and each trial that did not says where its plan first differs. A
refactor or a faster engine that keeps behaviour shows every trial the same (exit 0).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from stalm.cli.display import printable, shown
from stalm.cli.experiment_commands import console, out, read_results
from stalm.errors import StalmError
from stalm.geometry.tolerance import CONTINUOUS_TOLERANCE

commands = typer.Typer()
"""The top-level commands this module adds; :mod:`stalm.cli.main` composes them."""


@commands.command("same-plans")
def same_plans_command(
    before: Annotated[Path, typer.Argument(help="The results file (.jsonl) made before.")],
    after: Annotated[Path, typer.Argument(help="The results file made after, same seeds.")],
    tolerance: Annotated[
        float,
        typer.Option(help="Largest difference of a continuous value that is still the same."),
    ] = CONTINUOUS_TOLERANCE,
) -> None:
    """Compare what two results files' trials did, trial by trial (paired by row, problem
    and trial; seeds, problem files and budgets must match): the same termination, actions
    and continuous values within --tolerance. Times are not compared. Exit 1 if any trial
    differs, is not comparable or has no pair."""
    from stalm.experiments.markdown_cells import cell
    from stalm.experiments.plan_diff import VERDICTS, compare_plans

    if not tolerance >= 0:
        raise StalmError(f"--tolerance must be a number >= 0, got {tolerance!r}")
    comparison = compare_plans(
        read_results([before]), read_results([after]), tolerance, (str(before), str(after))
    )
    out.print(f"| row | problem | {' | '.join(VERDICTS)} |", highlight=False, soft_wrap=True)
    out.print("|" + " --- |" * (2 + len(VERDICTS)), highlight=False, soft_wrap=True)
    for (arm, problem), counts in comparison.counts().items():
        cells = " | ".join(str(counts.get(verdict, 0)) for verdict in VERDICTS)
        row = f"| {cell(printable(arm))} | {cell(printable(problem))} | {cells} |"
        out.print(row, highlight=False, markup=False, soft_wrap=True)
    for trial in comparison.trials:
        if trial.verdict != "same":
            line = f"{trial.arm} {trial.problem} trial {trial.trial}: {trial.verdict}"
            line += f": {trial.why}" if trial.why else ""
            out.print(printable(line), highlight=False, markup=False, soft_wrap=True)
    same = sum(trial.verdict == "same" for trial in comparison.trials)
    console.print(
        f"{same} of {len(comparison.trials)} trials executed the same plan in "
        f"{shown(before)} and {shown(after)}",
        highlight=False,
        soft_wrap=True,
    )
    if not comparison.all_same:
        raise typer.Exit(1)
