"""``stalm solve`` and ``stalm replay``: plan a problem end to end, re-check a saved plan."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from stalm.cli.display import shown
from stalm.cli.paths import check_output_file
from stalm.cli.physics_report import check_tolerance, print_physics
from stalm.cli.settings_options import SET_HELP, SETTINGS_HELP, command_settings, given
from stalm.cli.solve_output import (
    console,
    note_embedded,
    note_relevant_only,
    note_replay,
    out,
    solve_and_report,
    write_pictures,
    write_plan_gif,
)
from stalm.errors import StalmError
from stalm.viz.sizes import GIF_SIZE, MAX_SIZE, MIN_SIZE, check_size
from stalm.world.physics_check import SETTLE_SECONDS, TOLERANCE_DEG, TOLERANCE_M
from stalm.world.problem import load_problem
from stalm.world.problem_record import RECORD_PROBLEM_HELP, record_problem

GIF_SIZE_HELP = (
    f"Pixels of each of the animation's two square views (the GIF is twice as wide; "
    f"{MIN_SIZE} to {MAX_SIZE})."
)
PHYSICS_HELP = (
    f"Then run the plan under gravity: after each action the world settles {SETTLE_SECONDS:g} s "
    "and every object's move from where the plan puts it is measured; exit 1 beyond the "
    "tolerance."
)
PHYSICS_SOLVE_HELP = (
    "Then settle the solved plan under gravity as `stalm replay --physics` does (1 cm, 5 deg), "
    "record it in --json as 'physics', and exit 1 if an object moves further."
)
QUIET_HELP = (
    "Show no progress line while solving (it is shown only on a terminal: never in a pipe "
    "or a file)."
)
VERBOSE_HELP = (
    "Log each real step's decisions (the task plans proposed and what Concretize made of "
    "them, the search's rule, what was executed) on stderr, through Python's logging."
)

ROBOT_HELP = (
    "The robot to plan for instead of the problem's: a built-in robot (`stalm robot list`) "
    "or a robot file (a fixed one works a problem whose standing poses are all its own "
    "pose, as TABLE1's). The result records it."
)

commands = typer.Typer()
"""The top-level commands this module adds; :mod:`stalm.cli.main` composes them."""


def check_solve_numbers(seed: int, time_budget: float | None) -> None:
    """Numbers a solve cannot run with, as one StalmError naming the option, before the
    problem is loaded. ``--sims`` and ``--batch`` are checked where their keys are, by the
    settings tree, whose error names the option too."""
    from stalm.trial.result import check_seed, check_time_budget

    check_seed(seed, "--seed")  # the API's own checks: the same words
    check_time_budget(time_budget, "--time-budget")


SYMBOLIC_DEFAULT_NOTE = (
    "no language model named: task plans come from Fast Downward (--proposer symbolic). "
    "--llm embedded runs the bundled SmolLM2-135M; --llm openai:MODEL or "
    "--llm http://HOST:PORT/v1#MODEL a served model."
)


def default_proposer(planner: str, llm: str | None) -> str:
    """``symbolic`` for STaLM when no model is named (said on stderr), else ``llm``.

    A newcomer's first solve should solve: offline, the only model is the bundled 135M one,
    whose plans rarely ground, while the symbolic proposer solves P1-P6. Planners that have
    no symbolic proposer (EP-SayCan, LLM-MCTS, ...) keep the model.
    """
    from stalm.llm.backends import model_configured

    if planner in ("stalm", "stalm-no-uct") and not model_configured(llm):
        console.print(f"[yellow]note:[/] {SYMBOLIC_DEFAULT_NOTE}", highlight=False)
        return "symbolic"
    return "llm"


@commands.command("solve")
def solve_command(
    problem: Annotated[str, typer.Argument(help="Problem name (P5) or path to a problem file.")],
    llm: Annotated[
        str | None,
        typer.Option(
            help="Language model (llm.backend): 'embedded', 'openai:MODEL', 'ollama:MODEL', "
            "'vllm:MODEL', 'llamacpp', or a base URL 'http://host:port/v1#MODEL'. None named: "
            "STaLM runs on the symbolic proposer, and a planner that asks a model asks "
            "$STALM_LLM, else a server in $STALM_LLM_BASE_URL, else 'embedded'."
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random choice.")] = 0,
    time_budget: Annotated[
        float | None,
        typer.Option(
            "--time-budget", help="Seconds (budget.time_budget_s; default: the problem's)."
        ),
    ] = None,
    proposer_name: Annotated[
        str | None,
        typer.Option(
            "--proposer",
            help="Where task plans come from (proposer.kind): llm (a language model), "
            "symbolic (Fast Downward on the predicates, no model) or noisy (a degraded "
            "proposer, no model: Fast Downward's plans corrupted on purpose, see "
            "proposer.noise). Default: llm when a model is named (--llm, $STALM_LLM, "
            "$STALM_LLM_BASE_URL), else symbolic.",
        ),
    ] = None,
    planner_name: Annotated[
        str,
        typer.Option(
            "--planner",
            help="stalm (default) or a baseline: stalm-no-uct, uct, uct-hcount, ep-saycan, "
            "iterative-replanning, llm-mcts, pddlstream-adaptive (see `stalm planners`).",
        ),
    ] = "stalm",
    sims: Annotated[
        int | None,
        typer.Option(
            "--sims", help="N_budget (search.sims): simulations per step (30; 35 for uct)."
        ),
    ] = None,
    batch: Annotated[
        int | None, typer.Option("--batch", help="N_batch (search.batch): plans per query (5).")
    ] = None,
    no_uct: Annotated[bool, typer.Option("--no-uct", help="STaLM w/o UCT (Table 3).")] = False,
    constrained: Annotated[
        bool | None,
        typer.Option(
            "--constrained/--unconstrained",
            help="Constrain replies to the template and the problem's names (llm.constrained; "
            "default: on for the embedded model, which rarely writes a parseable plan "
            "otherwise; off for servers, as in the paper).",
        ),
    ] = None,
    no_occlusion: Annotated[
        bool, typer.Option("--no-occlusion", help="Prompt ablation (prompt.occlusion_predicates).")
    ] = False,
    no_challenges: Annotated[
        bool, typer.Option("--no-challenges", help="Prompt ablation (prompt.ask_challenges).")
    ] = False,
    cache: Annotated[
        str | None,
        typer.Option(
            help="Reply cache mode (llm.cache): use (default), refresh, off or replay (a miss "
            "is an error)."
        ),
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the result as JSON.")
    ] = None,
    gif: Annotated[
        Path | None, typer.Option("--gif", help="Write an animation of the plan.")
    ] = None,
    gif_size: Annotated[int, typer.Option("--gif-size", help=GIF_SIZE_HELP)] = GIF_SIZE,
    html: Annotated[
        Path | None,
        typer.Option("--html", help="Write the page of `stalm view` (scene, plan, search)."),
    ] = None,
    feedback: Annotated[
        bool | None,
        typer.Option(
            "--feedback/--no-feedback",
            help="Geometric feedback (execution.feedback): failed steps go back to the "
            "proposer, asked again (default: on with --proposer symbolic, off with a model, as "
            "in the paper, and with --proposer noisy).",
        ),
    ] = None,
    settings_file: Annotated[Path | None, typer.Option("--settings", help=SETTINGS_HELP)] = None,
    overrides: Annotated[list[str] | None, typer.Option("--set", help=SET_HELP)] = None,
    show_settings: Annotated[
        bool,
        typer.Option(
            "--show-settings",
            help="Print the resolved settings tree (YAML, usable as --settings) and exit "
            "without solving.",
        ),
    ] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help=QUIET_HELP)] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help=VERBOSE_HELP)] = False,
    physics: Annotated[bool, typer.Option("--physics", help=PHYSICS_SOLVE_HELP)] = False,
    robot: Annotated[str | None, typer.Option("--robot", help=ROBOT_HELP)] = None,
) -> None:
    """Solve a problem with STaLM (or a baseline) and execute the plan in simulation."""
    from stalm.planners.registry import planner_entry, resolve
    from stalm.settings.io import to_yaml, with_values

    check_solve_numbers(seed, time_budget)
    if not show_settings:
        for path, option in ((json_out, "--json"), (gif, "--gif"), (html, "--html")):
            if path is not None:
                check_output_file(path, option)
        check_size(gif_size, "--gif-size")
    loaded = load_problem(problem)
    if robot is not None:
        loaded = loaded.with_robot(robot)
    if no_uct:
        planner_name = "stalm-no-uct"
    entry = planner_entry(planner_name)
    flags = given(
        llm=("llm.backend", llm),
        proposer=("proposer.kind", proposer_name),
        sims=("search.sims", sims),
        batch=("search.batch", batch),
        time_budget=("budget.time_budget_s", time_budget),
        constrained=("llm.constrained", constrained),
        no_occlusion=("prompt.occlusion_predicates", False if no_occlusion else None),
        no_challenges=("prompt.ask_challenges", False if no_challenges else None),
        cache=("llm.cache", cache),
        feedback=("execution.feedback", feedback),
    )
    built = command_settings(settings_file, flags, overrides or ())
    settings = built.settings
    if "proposer.kind" not in built.named:
        kind = default_proposer(entry.name, settings.llm.backend)
        settings = with_values(settings, [("proposer.kind", kind)], "--proposer")
    resolved = resolve(entry.name, settings, loaded)
    if show_settings:
        out.print(
            f"# stalm solve {loaded.name} --planner {entry.name}: the resolved settings",
            highlight=False,
            markup=False,
        )
        out.print(to_yaml(resolved), highlight=False, markup=False, end="")
        return
    from stalm.motion.problem_check import check_problem_geometry
    from stalm.predicates.stuck import goal_unreachable

    with console.status(f"checking {shown(loaded.name)}'s scene..."):
        check_problem_geometry(loaded)  # before the clock starts: a bad file fails at once
        unreachable = goal_unreachable(loaded, resolved.predicates)
    if unreachable is not None:
        console.print(
            f"[yellow]warning:[/] {shown(loaded.source)}: the goal cannot be reached: "
            f"{shown(unreachable)}; the solve runs anyway (Ctrl-C stops it)",
            highlight=False,
            soft_wrap=True,
        )
    note_embedded(entry.name, resolved)
    note_replay(entry.name, resolved)
    note_relevant_only(loaded, settings, resolved)
    result, fallback, checked = solve_and_report(
        entry.name,
        resolved,
        loaded,
        seed,
        json_out,
        quiet=quiet,
        verbose=verbose,
        unreachable=unreachable,
        physics=physics,
    )
    write_pictures(loaded, result, resolved, gif, html, gif_size=gif_size, quiet=quiet)
    if fallback is not None:
        raise StalmError(f"--json {json_out} could not be written; the result is in {fallback}")
    if not result.success or (checked is not None and not checked.passed):
        raise typer.Exit(1)


@commands.command("replay")
def replay_command(
    result_file: Annotated[
        Path, typer.Argument(help="A JSON result written by stalm solve --json.")
    ],
    problem: Annotated[str | None, typer.Option(help=RECORD_PROBLEM_HELP)] = None,
    gif: Annotated[
        Path | None, typer.Option("--gif", help="Write an animation of the plan.")
    ] = None,
    gif_size: Annotated[int, typer.Option("--gif-size", help=GIF_SIZE_HELP)] = GIF_SIZE,
    physics: Annotated[bool, typer.Option("--physics", help=PHYSICS_HELP)] = False,
    physics_tolerance_m: Annotated[
        float,
        typer.Option(help="With --physics: how far an object may move (m, positive)."),
    ] = TOLERANCE_M,
    physics_tolerance_deg: Annotated[
        float,
        typer.Option(help="With --physics: how far an object may tilt (degrees, positive)."),
    ] = TOLERANCE_DEG,
) -> None:
    """Re-execute a saved plan in a fresh scene and check that it reaches the goal."""
    from stalm.trial.records import read_result
    from stalm.trial.replay import replay_result_json

    check_tolerance(physics_tolerance_m, "--physics-tolerance-m")
    check_tolerance(physics_tolerance_deg, "--physics-tolerance-deg")
    if gif is not None:
        check_output_file(gif, "--gif")
        check_size(gif_size, "--gif-size")
    data = read_result(result_file)  # bounded, finite, an object
    loaded = record_problem(data, str(result_file), problem, result_file.parent)
    report = replay_result_json(loaded, data)
    for warning in report.warnings:
        console.print(f"[yellow]warning:[/] {shown(warning)}", highlight=False, soft_wrap=True)
    if report.reached_goal:
        out.print(f"[green]replayed {report.steps_executed} actions: the goal is reached[/]")
    elif report.failed_step is not None:
        out.print(
            f"[red]step {report.failed_step + 1} fails:[/] {shown(report.reason)}",
            highlight=False,
            soft_wrap=True,  # one line, however long the reason
        )
    else:
        out.print(
            f"[red]replayed {report.steps_executed} actions: {shown(report.reason)}[/]",
            highlight=False,
        )
    if gif is not None:
        pairs = list(zip(report.actions, report.states[1:], strict=False))
        write_plan_gif(loaded, report.states[0], pairs, gif, gif_size)
    if not report.reached_goal:
        raise typer.Exit(1)
    if physics:
        from stalm.world.physics_check import check_physics

        with console.status("settling each step under gravity..."):
            labels = [str(action) for action in report.actions]
            checked = check_physics(
                loaded,
                report.states,
                labels,
                tolerance_m=physics_tolerance_m,
                tolerance_deg=physics_tolerance_deg,
            )
        print_physics(checked)
        if not checked.passed:
            raise typer.Exit(1)


@commands.command("planners")
def planners_command() -> None:
    """List every planner `stalm solve --planner` and `stalm experiment` accept."""
    from stalm.planners.registry import planners

    table = Table(show_header=True)
    table.add_column("planner")
    table.add_column("model")
    table.add_column("what it does")
    for entry in planners().values():
        table.add_row(entry.name, "yes" if entry.uses_llm else "no", entry.description)
    out.print(table)
