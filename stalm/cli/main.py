"""The ``stalm`` command: one Typer app composed here of the command modules' own apps.

Each command module defines its commands on a Typer of its own (``commands``, or a named group
such as ``bench_app``) and imports nothing back from here, so the modules form no import
circle. A :class:`~stalm.errors.StalmError` raised anywhere becomes one clear ``error:`` line
and exit code 2 instead of a traceback.
"""

from __future__ import annotations

import sys
import warnings
from typing import Any

import typer
from rich.console import Console

from stalm.cli import (
    bench_commands,
    compare_commands,
    experiment_commands,
    export_commands,
    generate_commands,
    llm_commands,
    predicate_commands,
    rerun_commands,
    robot_commands,
    solve_commands,
    view_commands,
    world_commands,
)
from stalm.cli.display import shown
from stalm.errors import StalmError, StalmWarning
from stalm.stopping import (
    Stopped,
    end_helper_processes,
    stop_code,
    stop_message,
    stopping_on_signals,
)
from stalm.temp_folders import remove_leftovers

app = typer.Typer(
    name="stalm",
    help="Geometric task and motion planning guided by language models (STaLM).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
# the order of `stalm --help`: top-level commands first, then the groups
for module in (
    experiment_commands,
    world_commands,
    predicate_commands,
    solve_commands,
    rerun_commands,
    compare_commands,
    view_commands,
    export_commands,
    generate_commands,
):
    app.add_typer(module.commands)
app.add_typer(bench_commands.bench_app, name="bench")
app.add_typer(llm_commands.llm_app, name="llm")
app.add_typer(robot_commands.robot_app, name="robot")

ERROR_CONSOLE = Console(stderr=True)


def main() -> None:
    """Entry point used by the console script: run the app, turn user errors into one line.

    Typer's own handling reports usage mistakes (exit code 2); a :class:`StalmError` raised by
    a command (bad file, unknown name, unreachable server) is printed as one ``error:`` line
    with exit code 2 instead of a traceback (quoted text escaped, see :mod:`stalm.cli.display`).
    TERM, HUP and INT stop the command with everything it started and exit 128 + the signal's
    number (:mod:`stalm.stopping`). Each command first removes the temporary folders that
    stalm processes killed outright left behind (:mod:`stalm.temp_folders`).
    """
    _one_line_warnings()
    remove_leftovers()
    code: int | str | None = 0
    try:
        with stopping_on_signals():
            try:
                app()
            except StalmError as error:
                # the message may quote a file, a reply or a server: escaped, never wrapped
                ERROR_CONSOLE.print(
                    f"[bold red]error:[/] {shown(error)}", highlight=False, soft_wrap=True
                )
                code = 2
            except (Stopped, KeyboardInterrupt) as stop:
                # whatever it interrupted has been cleaned up on the way here (stalm.stopping)
                ERROR_CONSOLE.print(f"[yellow]{stop_message(stop)}[/]", highlight=False)
                code = stop_code(stop)
                remove_leftovers(mine_too=True)  # one the signal cut off before its ``try``
    except SystemExit as done:
        code = done.code
    end_helper_processes()  # after the run's traceback and its pool are gone
    sys.exit(code)


def _one_line_warnings() -> None:
    """Show a :class:`StalmWarning` as one ``warning:`` line (other warnings as Python does):
    it tells the user something about their setup, not where in stalm's code it was noticed."""
    default = warnings.showwarning
    if getattr(default, "stalm_one_line", False):
        return  # already installed (main() run again in one process, as tests do)

    def show(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
        if issubclass(category, StalmWarning):
            ERROR_CONSOLE.print(
                f"[yellow]warning:[/] {shown(message)}", highlight=False, soft_wrap=True
            )
        else:
            default(message, category, *args, **kwargs)

    show.stalm_one_line = True  # type: ignore[attr-defined]
    warnings.showwarning = show
