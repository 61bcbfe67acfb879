"""``stalm problems`` and ``stalm render``: see what a problem holds and what it looks like."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from stalm.cli.display import shown
from stalm.cli.paths import check_output_file
from stalm.errors import StalmError
from stalm.files import read_json_file
from stalm.world.problem import Problem, available_problems, load_problem, no_problems_error
from stalm.world.state import State

commands = typer.Typer()
"""The top-level commands this module adds; :mod:`stalm.cli.main` composes them."""

console = Console()
warnings = Console(stderr=True)


def _problem_row(problem: Problem) -> tuple[str, ...]:
    spec = problem.spec
    goal = ", ".join(str(g) for g in problem.goal)
    cells = (
        spec.name,
        ", ".join(r.name for r in spec.regions),
        ", ".join(o.name for o in spec.objects),
        str(spec.placement_count),
        goal,
    )
    return tuple(shown(cell) for cell in cells)


def check_scenes(problems: list[Problem], show: Callable[[str], None]) -> None:
    """The simulator's check of each problem's scene (a StalmError naming the faults), then a
    warning per object no action can ever move and per object that does not rest where the
    file puts it; ``show`` hears what is being checked, object by object (a scene of 500
    objects takes minutes)."""
    from stalm.motion.problem_check import check_problem_geometry

    for problem in problems:
        name = shown(problem.name)
        show(f"checking {name}'s scene in the simulator...")
        check_problem_geometry(problem)

        def progress(done: int, total: int, name: str = name) -> None:
            show(f"checking {name}: can each object be picked and put down? {done} of {total}")

        _warn_stuck(problem, progress)
        show(f"checking {name}: does every object rest where the file puts it?")
        _warn_unsettled(problem)


def _warn_unsettled(problem: Problem) -> None:
    """A warning per object that moves or tips over under gravity from where the problem puts
    it (plans are kinematic: they would treat it as resting there)."""
    from stalm.world.physics_check import SETTLE_SECONDS, unsettled_objects

    for drift in unsettled_objects(problem):
        warnings.print(
            f"[yellow]warning:[/] {shown(problem.source)}: '{shown(drift.obj)}' does not rest "
            f"where the file puts it: under gravity it moved {drift.displacement_m * 100:.1f} "
            f"cm and tilted {drift.tilt_deg:.1f} deg in {SETTLE_SECONDS:g} s",
            highlight=False,
            soft_wrap=True,
        )


def _warn_stuck(problem: Problem, progress: Callable[[int, int], None]) -> None:
    """A warning per object no action can ever move (a goal needing it is unreachable)."""
    from stalm.motion.base_motion import BasePlanner
    from stalm.predicates.stuck import stuck_objects
    from stalm.world.scene import Sim

    with Sim(problem.spec) as sim:
        stuck = stuck_objects(problem, sim, BasePlanner(sim), progress=progress)
    goal_objects = {g.obj for g in problem.goal}
    for name, why in stuck.items():
        needed = " (the goal names it)" if name in goal_objects else ""
        warnings.print(
            f"[yellow]warning:[/] {shown(problem.source)}: '{shown(name)}' can never be "
            f"moved{needed}: {why}",
            highlight=False,
            soft_wrap=True,
        )


@commands.command("problems")
def problems_command(
    file: Annotated[
        list[Path] | None, typer.Option("--file", "-f", help="List these problem files instead.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
    check: Annotated[
        bool | None,
        typer.Option(
            "--check/--no-check",
            help="Also check the scene in the simulator: nothing starts inside anything, no two "
            "doors pass through each other, every standing pose is free and reachable, "
            "which objects can never be moved, and which do not rest under gravity where the "
            "file puts them (default: on for --file).",
        ),
    ] = None,
) -> None:
    """List the problems: regions, objects, placement count n(R) + 4 n(O), and goals.

    A problem file (YAML) is at most 1 MB; its coordinates, sizes and angles lie within
    +-1000 (m, rad), its floor is at most 100 m on a side, its colours' channels in [0, 1],
    and its names are identifiers of up to 64 letters, digits and '_' (quote a key or
    direction `on`: YAML reads it bare as true)."""
    problems = (
        [load_problem(path) for path in file]
        if file
        else [load_problem(p) for p in available_problems()]
    )
    if not problems:
        raise no_problems_error()  # an empty table would look like success
    if check if check is not None else bool(file):
        with console.status("checking the scenes in the simulator...") as status:
            check_scenes(problems, status.update)
    if as_json:
        rows = [
            {
                "name": pr.name,
                "source": pr.source,
                "regions": [r.name for r in pr.spec.regions],
                "objects": [o.name for o in pr.spec.objects],
                "doors": [d.name for d in pr.spec.doors],
                "placements": pr.spec.placement_count,
                "goal": [[g.obj, g.direction, g.ref] for g in pr.goal],
            }
            for pr in problems
        ]
        typer.echo(json.dumps(rows, indent=2))
        return
    table = Table(title="stalm problems", show_lines=True)
    for column in ("problem", "regions", "objects", "placements", "goal"):
        table.add_column(column, overflow="fold")
    for pr in problems:
        table.add_row(*_problem_row(pr))
    console.print(table)


@commands.command("render")
def render_command(
    problem: Annotated[str, typer.Argument(help="Problem name (P5) or path to a problem file.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="PNG file to write.")] = Path(
        "scene.png"
    ),
    state_file: Annotated[
        Path | None, typer.Option("--state", help="Render this State (JSON, as in result files).")
    ] = None,
    size: Annotated[int, typer.Option(help="Pixel size of each view (16-4096).")] = 640,
) -> None:
    """Write a top-down and a perspective image of the initial state (or a given State)."""
    from stalm.viz.render import check_size, save_render
    from stalm.world.scene import Sim

    check_size(size, "--size")
    check_output_file(output, "--output")
    loaded = load_problem(problem)
    state = loaded.initial_state
    if state_file is not None:
        state = read_state_file(state_file, loaded)
    with Sim(loaded.spec) as sim:
        save_render(sim, state, output, size)
    console.print(f"wrote {shown(output)}", highlight=False)


def read_state_file(path: Path, problem: Problem | None = None) -> State:
    """A State from a JSON file (a bare State, or any JSON object with a 'state' field).

    With ``problem``, the State must hold exactly the problem's objects and only its doors,
    so the simulator is never asked to place a body it does not have.
    """
    data = read_json_file(path, "State file")  # a regular file, bounded, not too deep
    if isinstance(data, dict) and "state" in data:
        data = data["state"]
    try:
        state = State.from_json(data)
    except (KeyError, TypeError, ValueError, OverflowError) as error:
        raise StalmError(f"{path}: not a State ({error})") from None
    if problem is not None:
        why = problem.state_mismatch(state)
        if why is not None:
            raise StalmError(f"{path}: not a State of {problem.name}: {why}")
    return state
