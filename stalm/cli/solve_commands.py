"""``stalm solve`` and ``stalm replay``: plan a problem end to end, re-check a saved plan."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from stalm.cli.display import shown
from stalm.cli.paths import check_output_file, write_or_fall_back
from stalm.domain.params import PickParams, PlaceParams
from stalm.errors import StalmError
from stalm.planners.base import PlanResult
from stalm.world.problem import PROBLEM_HASH_FIELD, load_problem

commands = typer.Typer()
"""The top-level commands this module adds; :mod:`stalm.cli.main` composes them."""

console = Console(stderr=True)
out = Console()


def _print_result(result: PlanResult) -> None:
    status = (
        "[green]solved[/]"
        if result.success
        else f"[red]not solved[/] ({shown(result.termination)})"
    )
    out.print(
        f"{shown(result.problem)} with {result.planner} (seed {result.seed}): {status}",
        highlight=False,
    )
    table = Table(show_header=True, title=f"plan ({len(result.plan)} actions)")
    table.add_column("#", justify="right")
    table.add_column("action")
    table.add_column("continuous parameters")
    for index, action in enumerate(result.plan):
        params = action.params
        detail = f"base path {params.base_path.length:.2f} m"
        if isinstance(params, PickParams):
            detail += f", gripper pitch {params.pitch:.2f} yaw {params.yaw:.2f}"
        elif isinstance(params, PlaceParams):
            detail += f", at ({params.placement.x:.2f}, {params.placement.y:.2f})"
        table.add_row(str(index + 1), shown(action.discrete), detail)
    out.print(table)
    t = result.times
    c = result.counters
    out.print(
        f"time {t.total:.1f} s (predicates {t.predicates:.1f}, LLM {t.llm:.1f}, concretize "
        f"{t.concretize:.1f}, tree {t.tree_search:.1f}, execution {t.execution:.1f}); "
        f"LLM calls {c.llm_calls} ({c.prompt_tokens}+{c.completion_tokens} tokens), "
        f"T calls {c.transitions}, samples {c.samples}, simulations {c.simulations}, "
        f"collision checks {c.collision_checks}",
        highlight=False,
    )
    if result.llm_plan_failures:
        out.print(f"failed task plans by kind: {shown(result.llm_plan_failures)}", highlight=False)


def write_result_json(data: dict[str, Any], path: Path) -> Path:
    """Write a result; if ``path`` cannot be written, to a temporary file named on stderr
    (a solve's result is never lost to a bad path). Returns the file written."""
    written, why = write_or_fall_back(json.dumps(data, indent=1), path, "stalm-result")
    if why is not None:
        console.print(
            f"[red]could not write {shown(path)}[/] ({shown(why)}); the result is in "
            f"{shown(written)}",
            highlight=False,
            soft_wrap=True,
        )
    return written


def check_solve_numbers(seed: int, time_budget: float | None, sims: int | None, batch: int) -> None:
    """Numbers a solve cannot run with, as one StalmError naming the option."""
    if seed < 0:
        raise StalmError(f"--seed must be a non-negative integer, got {seed}")
    if time_budget is not None and not (math.isfinite(time_budget) and time_budget > 0):
        raise StalmError(f"--time-budget must be a positive number of seconds, got {time_budget}")
    if sims is not None and sims < 1:
        raise StalmError(f"--sims (N_budget) must be at least 1, got {sims}")
    if batch < 1:
        raise StalmError(f"--batch (N_batch) must be at least 1, got {batch}")


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
            help="Language model: 'embedded' (default), 'openai:MODEL', 'ollama:MODEL', "
            "'vllm:MODEL', 'llamacpp', or a base URL 'http://host:port/v1#MODEL'."
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random choice.")] = 0,
    time_budget: Annotated[
        float | None, typer.Option("--time-budget", help="Seconds (default: the problem's).")
    ] = None,
    proposer_name: Annotated[
        str | None,
        typer.Option(
            "--proposer",
            help="Where task plans come from: llm (a language model) or symbolic (Fast "
            "Downward on the predicates, no model). Default: llm when a model is named "
            "(--llm, $STALM_LLM, $STALM_LLM_BASE_URL), else symbolic.",
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
        typer.Option("--sims", help="N_budget: simulations per step (default 30; 35 for uct)."),
    ] = None,
    batch: Annotated[int, typer.Option("--batch", help="N_batch: task plans per query.")] = 5,
    no_uct: Annotated[bool, typer.Option("--no-uct", help="STaLM w/o UCT (Table 3).")] = False,
    constrained: Annotated[
        bool | None,
        typer.Option(
            "--constrained/--unconstrained",
            help="Constrain replies to the template and the problem's names (default: on for "
            "the embedded model, which rarely writes a parseable plan otherwise; off for "
            "servers, as in the paper).",
        ),
    ] = None,
    no_occlusion: Annotated[bool, typer.Option("--no-occlusion", help="Prompt ablation.")] = False,
    no_challenges: Annotated[
        bool, typer.Option("--no-challenges", help="Prompt ablation.")
    ] = False,
    cache: Annotated[
        str,
        typer.Option(help="Reply cache mode: use, refresh, off or replay (a miss is an error)."),
    ] = "use",
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the result as JSON.")
    ] = None,
    gif: Annotated[
        Path | None, typer.Option("--gif", help="Write an animation of the plan.")
    ] = None,
    html: Annotated[
        Path | None,
        typer.Option("--html", help="Write the page of `stalm view` (scene, plan, search)."),
    ] = None,
    feedback: Annotated[
        bool | None,
        typer.Option(
            "--feedback/--no-feedback",
            help="Geometric feedback: failed steps go back to the proposer, asked again "
            "(default: on with --proposer symbolic, off with a model, as in the paper).",
        ),
    ] = None,
    overrides: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            help="Planner setting KEY=VALUE (repeatable): reuse_tree, execution "
            "(progress|best_q), kappa_tries, goal_atom_lost, goal_relations_only, feedback, "
            "sims, batch.",
        ),
    ] = None,
) -> None:
    """Solve a problem with STaLM (or a baseline) and execute the plan in simulation."""
    from stalm.llm.prompt import PromptOptions
    from stalm.planners.registry import (
        PlannerConfig,
        build_planner,
        planner_entry,
        with_overrides,
    )

    check_solve_numbers(seed, time_budget, sims, batch)
    for path, option in ((json_out, "--json"), (gif, "--gif"), (html, "--html")):
        if path is not None:
            check_output_file(path, option)
    loaded = load_problem(problem)
    from stalm.motion.problem_check import check_problem_geometry

    with console.status(f"checking {shown(loaded.name)}'s scene..."):
        check_problem_geometry(loaded)  # before the clock starts: a bad file fails at once
    if no_uct:
        planner_name = "stalm-no-uct"
    entry = planner_entry(planner_name)
    if proposer_name is None:
        proposer_name = default_proposer(entry.name, llm)
    config = PlannerConfig(
        llm=llm,
        proposer=proposer_name,
        sims=sims,
        batch=batch,
        constrained=constrained,
        prompt=PromptOptions(
            occlusion_predicates=not no_occlusion, ask_challenges=not no_challenges
        ),
        cache_mode=cache,
        feedback=feedback,
    )
    config = with_overrides(config, overrides or ())
    symbolic = proposer_name == "symbolic" and entry.name in ("stalm", "stalm-no-uct")
    if entry.uses_llm and not symbolic:
        from stalm.llm.backends import make_backend

        backend = make_backend(llm)  # no model is loaded here
        if backend.name == "embedded":
            console.print(f"[yellow]note:[/] {shown(backend.description)}", highlight=False)
    with console.status(f"solving {shown(loaded.name)} with {entry.name}...") as status:
        planner = build_planner(entry.name, config, progress=lambda m: status.update(shown(m)))
        try:
            result = planner.solve(loaded, seed, time_budget)
        except StalmError as error:
            # a server that fails mid-run (a key refused, answers that are not JSON): the
            # result file still says what happened, as an experiment's error record does
            if json_out is not None:
                failed = {
                    "problem": loaded.name,
                    PROBLEM_HASH_FIELD: loaded.content_hash,
                    "planner": entry.name,
                    "seed": seed,
                    "success": False,
                    "termination": "error",
                    "error": str(error),
                    "plan_length": 0,
                    "plan": [],
                }
                out.print(f"wrote {shown(write_result_json(failed, json_out))}", highlight=False)
            raise
    _print_result(result)
    fallback: Path | None = None
    if json_out is not None:
        data = {**result.to_json(), PROBLEM_HASH_FIELD: loaded.content_hash}
        written = write_result_json(data, json_out)
        out.print(f"wrote {shown(written)}", highlight=False)
        fallback = written if written != json_out else None
    if gif is not None:
        _write_gif(loaded, result, gif)
    if html is not None:
        from stalm.cli.view_commands import write_view_page

        write_view_page(loaded, {**result.to_json(), PROBLEM_HASH_FIELD: loaded.content_hash}, html)
    if fallback is not None:
        raise StalmError(f"--json {json_out} could not be written; the result is in {fallback}")
    if not result.success:
        raise typer.Exit(1)


def _write_gif(problem: object, result: PlanResult, path: Path) -> None:
    from stalm.viz.animate import plan_frames, save_gif
    from stalm.world.scene import Sim

    assert hasattr(problem, "spec")
    with Sim(problem.spec) as sim, console.status("rendering the animation..."):
        frames = plan_frames(
            sim, result.states[0], list(zip(result.plan, result.states[1:], strict=True))
        )
        try:
            save_gif(frames, path)
        except OSError as error:
            raise StalmError(f"--gif {path}: cannot write it ({error.strerror})") from None
    out.print(f"wrote {shown(path)} ({len(frames)} frames)", highlight=False)


@commands.command("replay")
def replay_command(
    result_file: Annotated[
        Path, typer.Argument(help="A JSON result written by stalm solve --json.")
    ],
    problem: Annotated[
        str | None, typer.Option(help="Problem (default: the one named in the file).")
    ] = None,
    gif: Annotated[
        Path | None, typer.Option("--gif", help="Write an animation of the plan.")
    ] = None,
) -> None:
    """Re-execute a saved plan in a fresh scene and check that it reaches the goal."""
    from stalm.planners.replay import replay_result_json

    if gif is not None:
        check_output_file(gif, "--gif")
    try:
        data = json.loads(result_file.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:  # ValueError: not UTF-8, not JSON
        raise StalmError(f"{result_file}: cannot read a result ({error})") from None
    if not isinstance(data, dict):
        raise StalmError(f"{result_file}: not a stalm result (not a JSON object)")
    loaded = load_problem(problem or str(data.get("problem", "")))
    report = replay_result_json(loaded, data)
    for warning in report.warnings:
        console.print(f"[yellow]warning:[/] {shown(warning)}", highlight=False, soft_wrap=True)
    if report.reached_goal:
        out.print(f"[green]replayed {report.steps_executed} actions: the goal is reached[/]")
    elif report.failed_step is not None:
        out.print(
            f"[red]step {report.failed_step + 1} fails:[/] {shown(report.reason)}", highlight=False
        )
    else:
        out.print(
            f"[red]replayed {report.steps_executed} actions: {shown(report.reason)}[/]",
            highlight=False,
        )
    if gif is not None:
        from stalm.viz.animate import plan_frames, save_gif
        from stalm.world.scene import Sim

        with Sim(loaded.spec) as sim:
            pairs = list(zip(report.actions, report.states[1:], strict=False))
            save_gif(plan_frames(sim, report.states[0], pairs), gif)
    if not report.reached_goal:
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
