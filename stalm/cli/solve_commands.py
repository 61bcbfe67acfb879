"""``stalm solve`` and ``stalm replay``: plan a problem end to end, re-check a saved plan."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from stalm.cli.main import app
from stalm.domain.params import PickParams, PlaceParams
from stalm.errors import StalmError
from stalm.planners.base import PlanResult
from stalm.world.problem import load_problem

console = Console(stderr=True)
out = Console()


def _print_result(result: PlanResult) -> None:
    status = "[green]solved[/]" if result.success else f"[red]not solved[/] ({result.termination})"
    out.print(
        f"{result.problem} with {result.planner} (seed {result.seed}): {status}", highlight=False
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
        table.add_row(str(index + 1), str(action.discrete), detail)
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
        out.print(f"failed task plans by kind: {result.llm_plan_failures}", highlight=False)


@app.command("solve")
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
        str,
        typer.Option(
            "--proposer",
            help="Where task plans come from: llm (default) or symbolic (Fast Downward on the "
            "predicates, no model).",
        ),
    ] = "llm",
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

    loaded = load_problem(problem)
    if no_uct:
        planner_name = "stalm-no-uct"
    entry = planner_entry(planner_name)
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
            console.print(f"[yellow]note:[/] {backend.description}", highlight=False)
    with console.status(f"solving {loaded.name} with {entry.name}...") as status:
        planner = build_planner(entry.name, config, progress=lambda m: status.update(m))
        result = planner.solve(loaded, seed, time_budget)
    _print_result(result)
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(result.to_json(), indent=1))
        out.print(f"wrote {json_out}")
    if gif is not None:
        _write_gif(loaded, result, gif)
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
        save_gif(frames, path)
    out.print(f"wrote {path} ({len(frames)} frames)")


@app.command("replay")
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

    try:
        data = json.loads(result_file.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as error:
        raise StalmError(f"{result_file}: cannot read a result ({error})") from None
    loaded = load_problem(problem or str(data.get("problem", "")))
    report = replay_result_json(loaded, data)
    if report.reached_goal:
        out.print(f"[green]replayed {report.steps_executed} actions: the goal is reached[/]")
    elif report.failed_step is not None:
        out.print(f"[red]step {report.failed_step + 1} fails:[/] {report.reason}", highlight=False)
    else:
        out.print(
            f"[red]replayed {report.steps_executed} actions: {report.reason}[/]", highlight=False
        )
    if gif is not None:
        from stalm.viz.animate import plan_frames, save_gif
        from stalm.world.scene import Sim

        with Sim(loaded.spec) as sim:
            pairs = list(zip(report.actions, report.states[1:], strict=False))
            save_gif(plan_frames(sim, report.states[0], pairs), gif)
    if not report.reached_goal:
        raise typer.Exit(1)


@app.command("planners")
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
