"""The ``stalm`` command: one Typer app; each command group lives in its own module.

Command modules register themselves by being imported here. A :class:`~stalm.errors.StalmError`
raised anywhere becomes one clear ``error:`` line and exit code 2 instead of a traceback.
"""

from __future__ import annotations

import sys

import typer
from rich.console import Console

from stalm.errors import StalmError

app = typer.Typer(
    name="stalm",
    help="Geometric task and motion planning guided by language models (STaLM).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

ERROR_CONSOLE = Console(stderr=True)


def _register_commands() -> None:
    """Import the command modules; each adds its commands to :data:`app` (once)."""
    from stalm.cli import (  # noqa: F401
        bench_commands,
        experiment_commands,
        llm_commands,
        predicate_commands,
        solve_commands,
        view_commands,
        world_commands,
    )

    if not any(group.name == "llm" for group in app.registered_groups):
        app.add_typer(llm_commands.llm_app, name="llm")


def main() -> None:
    """Entry point used by the console script: run the app, turn user errors into one line.

    Typer's own handling reports usage mistakes (exit code 2); a :class:`StalmError` raised by
    a command (bad file, unknown name, unreachable server) is printed as one ``error:`` line
    with exit code 2 instead of a traceback (quoted text escaped, see :mod:`stalm.cli.display`).
    """
    from stalm.cli.display import shown

    _register_commands()
    try:
        app()
    except StalmError as error:
        # the message may quote a file, a reply or a server: escaped, and never wrapped
        ERROR_CONSOLE.print(f"[bold red]error:[/] {shown(error)}", highlight=False, soft_wrap=True)
        sys.exit(2)
