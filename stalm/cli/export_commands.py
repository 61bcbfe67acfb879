"""``stalm export``: a result's executed plan as timed trajectories a robot can run (the fields
of ROS's ``trajectory_msgs/JointTrajectory``; :mod:`stalm.trial.export`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from stalm.cli.display import shown
from stalm.cli.paths import check_output_file
from stalm.errors import StalmError
from stalm.files import write_replacing
from stalm.trial.export import DEFAULT_RATE, RATE_RANGE, check_rate
from stalm.world.problem_record import RECORD_PROBLEM_HELP, record_problem

console = Console(stderr=True)
out = Console()
commands = typer.Typer()
"""The ``export`` command, composed into the ``stalm`` app by :mod:`stalm.cli.main`."""


def default_output(result_file: Path) -> Path:
    """``p5.json`` -> ``p5.trajectories.json``, beside the result."""
    return result_file.with_name(f"{result_file.stem}.trajectories.json")


@commands.command("export")
def export_command(
    result_file: Annotated[
        Path, typer.Argument(help="A JSON result written by stalm solve --json.")
    ],
    output: Annotated[
        Path | None,
        typer.Option(
            "--output", "-o", help="The file to write (default: RESULT.trajectories.json)."
        ),
    ] = None,
    rate: Annotated[
        float,
        typer.Option(
            help=f"Samples a second of each trajectory ({RATE_RANGE[0]:g}-{RATE_RANGE[1]:g} Hz), "
            "besides every waypoint and the end."
        ),
    ] = DEFAULT_RATE,
    problem: Annotated[str | None, typer.Option(help=RECORD_PROBLEM_HELP)] = None,
) -> None:
    """Write the executed plan as timed trajectories: the base path and each arm motion,
    time-parameterised under the robot's velocity and acceleration limits, with the grasp,
    release and door events.

    The plan is replayed in a fresh scene first; a plan that does not replay is refused."""
    from stalm.trial.export import export_result
    from stalm.trial.records import read_result

    target = output if output is not None else default_output(result_file)
    check_output_file(target, "--output")
    check_rate(rate)
    data = read_result(result_file)  # bounded, finite, an object
    loaded = record_problem(data, str(result_file), problem, result_file.parent)
    with console.status("replaying and timing the plan..."):
        exported, warnings = export_result(loaded, data, rate, source=result_file.name)
    for warning in warnings:
        console.print(f"[yellow]warning:[/] {shown(warning)}", highlight=False, soft_wrap=True)
    try:
        write_replacing(target, json.dumps(exported) + "\n")
    except OSError as error:
        why = error.strerror or error
        raise StalmError(f"--output {target}: cannot write it ({why})") from None
    points = sum(len(t["points"]) for t in exported["trajectories"])
    out.print(
        f"wrote {shown(target)}: {len(exported['trajectories'])} trajectories, {points} points "
        f"at {rate:g} Hz, {len(exported['events'])} events, {exported['duration']:.1f} s of "
        "robot time",
        highlight=False,
    )
