"""``stalm replay --physics`` and ``stalm solve --physics``: the options checked, the check run
and its report printed, one line a step."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from rich.console import Console

from stalm.cli.display import shown
from stalm.errors import StalmError
from stalm.world.physics_check import PhysicsReport, StepCheck, check_physics
from stalm.world.problem import Problem

if TYPE_CHECKING:
    from stalm.trial.result import PlanResult

console = Console(stderr=True)
out = Console()


def check_tolerance(value: float, option: str) -> None:
    """A tolerance must be a positive finite number; a StalmError names the option if not."""
    if not (math.isfinite(value) and value > 0):
        raise StalmError(f"{option} must be a positive number, not {value:g}")


def physics_of(problem: Problem, result: PlanResult) -> PhysicsReport:
    """The physics check of a solved plan's executed states, printed."""
    with console.status("settling each step under gravity..."):
        checked = check_physics(problem, result.states, [str(a) for a in result.plan])
    print_physics(checked)
    return checked


def print_physics(report: PhysicsReport) -> None:
    """Each step's largest move and tilt, then the verdict (the failure in one line)."""
    for step in report.steps:
        out.print(f"  {_step_line(step)}", highlight=False, soft_wrap=True)
    failure = report.failure_line()
    if failure is None:
        out.print(
            f"[green]physics check passed:[/] every object within {report.tolerance_m * 100:g} "
            f"cm and {report.tolerance_deg:g} deg after each step settled "
            f"{report.settle_seconds:g} s",
            highlight=False,
            soft_wrap=True,
        )
    else:
        out.print(f"[red]{shown(failure)}[/]", highlight=False, soft_wrap=True)


def _step_line(step: StepCheck) -> str:
    where = f"step {step.step} ({shown(step.label)}):"
    if step.largest_move is None or step.largest_tilt is None:
        return f"{where} no object rests"
    moved, tilted = step.largest_move, step.largest_tilt
    return (
        f"{where} largest move {moved.displacement_m * 1000:.2f} mm ({shown(moved.obj)}), "
        f"largest tilt {tilted.tilt_deg:.2f} deg ({shown(tilted.obj)})"
    )
