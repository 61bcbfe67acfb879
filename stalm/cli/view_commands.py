"""``stalm view``: a result file as one HTML page (the scene animated through the plan, the
plan's parameters, and per real step the task plans, their failures and the search tree)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from stalm.cli.display import shown
from stalm.cli.paths import check_output_file
from stalm.world.problem import Problem
from stalm.world.problem_record import RECORD_PROBLEM_HELP, record_problem

console = Console(stderr=True)
out = Console()
commands = typer.Typer()
"""The ``view`` command, composed into the ``stalm`` app by :mod:`stalm.cli.main`."""


def write_view_page(problem: Problem, data: dict[str, Any], path: Path, source: str = "") -> None:
    """Build the page of the result ``data`` (planned for ``problem``) and write it to
    ``path``; used by ``stalm view`` and ``stalm solve --html``."""
    from stalm.viz.view_data import view_data
    from stalm.viz.view_page import write_page

    with console.status("building the page (replaying the plan)..."):
        size = write_page(view_data(problem, data, source), path)
    out.print(f"wrote {shown(path)} ({size / 1e6:.1f} MB, opens offline)", highlight=False)


@commands.command("view")
def view_command(
    result_file: Annotated[
        Path, typer.Argument(help="A JSON result written by stalm solve --json.")
    ],
    output: Annotated[
        Path | None,
        typer.Option("--output", "-o", help="The page to write (default: RESULT with .html)."),
    ] = None,
    problem: Annotated[str | None, typer.Option(help=RECORD_PROBLEM_HELP)] = None,
) -> None:
    """Write a self-contained HTML page of a result, the scene animated through the plan.

    The page also shows the plan's continuous parameters and, per real step, the task plans,
    why each failed, and the search tree."""
    from stalm.trial.records import read_result

    page = output if output is not None else result_file.with_suffix(".html")
    check_output_file(page, "--output")
    data = read_result(result_file)
    loaded = record_problem(data, str(result_file), problem, result_file.parent)
    write_view_page(loaded, data, page, source=result_file.name)
