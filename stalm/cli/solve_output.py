"""Running one solve and showing it: what ``stalm solve`` and ``stalm rerun`` share.

:func:`solve_and_report` builds the planner from a resolved settings tree, solves with the
tree's budget, prints the plan, its phase times and counters, and writes the result record
(``--json``), which carries the problem (its spec and hash) and the whole settings tree, so
that ``stalm rerun`` can run the trial again from the file alone.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.table import Table

from stalm.cli.display import shown
from stalm.cli.paths import write_or_fall_back
from stalm.errors import StalmError
from stalm.trial.details import UnreachableGoal
from stalm.world.problem import Problem
from stalm.world.problem_record import problem_fields

if TYPE_CHECKING:
    from stalm.domain.params import Action
    from stalm.settings.tree import RunSettings
    from stalm.trial.result import PlanResult
    from stalm.world.physics_check import PhysicsReport
    from stalm.world.state import State

console = Console(stderr=True)
out = Console()


def print_result(result: PlanResult) -> None:
    """The outcome, the plan with its continuous parameters, phase times and counters."""
    from stalm.domain.params import PickParams, PlaceParams

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
        f"time {t.total:.1f} s (set-up {t.setup:.1f}, predicates {t.predicates:.1f}, "
        f"{proposer_label(result)} {t.proposer:.1f}, concretize "
        f"{t.concretize:.1f}, tree {t.tree_search:.1f}, execution {t.execution:.1f}); "
        f"LLM calls {c.llm_calls} ({c.prompt_tokens}+{c.completion_tokens} tokens), "
        f"T calls {c.transitions}, samples {c.samples}, simulations {c.simulations}, "
        f"collision checks {c.collision_checks}",
        highlight=False,
    )
    if result.llm_plan_failures:
        out.print(f"failed task plans by kind: {shown(result.llm_plan_failures)}", highlight=False)


def proposer_label(result: PlanResult) -> str:
    """What the proposer phase of a result's times was: Fast Downward's runs (the symbolic
    proposer, and the noisy one around it) or a language model's calls."""
    name = result.details.proposer or ""
    if name.startswith("symbolic") or (name.startswith("noisy") and "symbolic" in name):
        return "proposer (Fast Downward)"
    if name.startswith(("llm", "noisy")) or result.counters.llm_calls:
        return "proposer (model)"
    return "proposer"


def print_timeout_advice(result: PlanResult, problem: Problem, settings: RunSettings) -> None:
    """After a timeout: the phase that took the most of the time and the setting to try."""
    from stalm.planners.registry import asks_model
    from stalm.trial.timeout_advice import timeout_advice

    asked = asks_model(result.planner, settings)
    advice = timeout_advice(result.times, settings, len(problem.spec.objects), asked)
    console.print(f"[yellow]timed out:[/] {shown(advice.text())}", highlight=False, soft_wrap=True)


UNREACHABLE_GOAL = "unreachable_goal"
"""The termination of a solve that did not reach a goal the problem check had found
unreachable: the cause, where the run's own end ('timeout', 'horizon') is only the symptom."""


def with_unreachable_goal(result: PlanResult, why: str) -> PlanResult:
    """``result`` (a run that did not reach its goal) ending as :data:`UNREACHABLE_GOAL`; its
    details keep ``why`` and how the run itself ended."""
    details = replace(result.details, unreachable_goal=UnreachableGoal(why, result.termination))
    return replace(result, termination=UNREACHABLE_GOAL, details=details)


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


def result_record(result: PlanResult, problem: Problem, settings: RunSettings) -> dict[str, Any]:
    """What ``--json`` writes: the result, the problem (its name, hash and spec: the record
    reopens without the file) and the whole settings tree."""
    from stalm.settings.io import to_dict

    return {**result.to_json(), **problem_fields(problem), "settings": to_dict(settings)}


def note_embedded(planner: str, settings: RunSettings) -> None:
    """Say so when a planner that asks a model will ask the bundled small one."""
    from stalm.llm.backends import make_backend
    from stalm.planners.registry import asks_model

    if not asks_model(planner, settings):
        return
    backend = make_backend(settings.llm.backend)  # no model is loaded here
    if backend.name == "embedded":
        console.print(f"[yellow]note:[/] {shown(backend.description)}", highlight=False)


def note_relevant_only(problem: Problem, given: RunSettings, resolved: RunSettings) -> None:
    """Say so, in one line, when a problem's size turned relevant-only predicates on."""
    if given.predicates.relevant_only or not resolved.predicates.relevant_only:
        return
    console.print(
        f"[yellow]note:[/] {len(problem.spec.objects)} objects, more than "
        f"predicates.relevant_above ({given.predicates.relevant_above}): occlusions only for "
        "the objects a plan must touch (predicates.relevant_only); --set "
        "predicates.relevant_above=null for the paper's",
        highlight=False,
        soft_wrap=True,
    )


def note_replay(planner: str, settings: RunSettings) -> None:
    """Say whose replies a replay serves (a model name alone does not tell) and from where."""
    from stalm.llm.backends.identity import spec_identity
    from stalm.llm.cache_file import default_cache_path
    from stalm.planners.registry import asks_model

    llm = settings.llm
    if llm.cache != "replay" or llm.from_record or not asks_model(planner, settings):
        return
    whose = spec_identity(llm.backend).describe()  # builds nothing, contacts nothing
    where = llm.cache_file or default_cache_path()
    console.print(
        f"[yellow]note:[/] replaying the replies of {shown(whose)} from {shown(where)}; "
        "no model is run",
        highlight=False,
        soft_wrap=True,
    )


def solve_and_report(
    planner_name: str,
    settings: RunSettings,
    problem: Problem,
    seed: int,
    json_out: Path | None,
    *,
    quiet: bool = False,
    verbose: bool = False,
    unreachable: str | None = None,
    physics: bool = False,
) -> tuple[PlanResult, Path | None, PhysicsReport | None]:
    """Solve ``problem`` with the resolved ``settings``, print the result and write its
    record to ``json_out`` (also when a server stops the run: then termination 'error').
    Returns the result and the file the record went to instead of ``json_out``, if any.

    On a terminal a progress line shows where the solve is, unless ``quiet``
    (:mod:`stalm.cli.solve_progress`); ``verbose`` logs each real step's decisions.
    ``unreachable``: why the problem check found the goal unreachable; a run that then does
    not reach it ends as 'unreachable_goal' (:func:`with_unreachable_goal`), not as a bare
    'timeout'. ``physics``: a plan that reaches the goal is then settled under gravity
    (:func:`~stalm.world.physics_check.check_physics`), printed, recorded as ``physics`` and
    returned."""
    from stalm.cli.solve_progress import solve_progress, verbose_logging
    from stalm.planners.registry import build_planner
    from stalm.settings.io import to_dict
    from stalm.settings.tree import with_budget

    title = f"solving {problem.name} with {planner_name}..."
    with (
        verbose_logging(console, verbose),
        solve_progress(console, title, quiet) as observer,
    ):
        planner = build_planner(planner_name, settings, progress=observer)
        try:
            result = planner.solve(
                with_budget(problem, settings.budget), seed, settings.budget.time_budget_s
            )
        except StalmError as error:
            # a server that fails mid-run (a key refused, answers that are not JSON): the
            # result file still says what happened, as an experiment's error record does
            if json_out is not None:
                failed = {
                    **problem_fields(problem),
                    "planner": planner_name,
                    "seed": seed,
                    "success": False,
                    "termination": "error",
                    "error": str(error),
                    "plan_length": 0,
                    "plan": [],
                    "settings": to_dict(settings),
                }
                out.print(f"wrote {shown(write_result_json(failed, json_out))}", highlight=False)
            raise
    if unreachable is not None and not result.success:
        result = with_unreachable_goal(result, unreachable)
    print_result(result)
    if result.termination == UNREACHABLE_GOAL:
        console.print(
            f"[yellow]the goal cannot be reached:[/] {shown(unreachable)}",
            highlight=False,
            soft_wrap=True,
        )
    elif result.termination == "timeout":
        print_timeout_advice(result, problem, settings)
    checked = None
    if physics and result.success:
        from stalm.cli.physics_report import physics_of

        checked = physics_of(problem, result)
    fallback: Path | None = None
    if json_out is not None:
        record = result_record(result, problem, settings)
        if checked is not None:
            record["physics"] = checked.to_json()
        written = write_result_json(record, json_out)
        out.print(f"wrote {shown(written)}", highlight=False)
        fallback = written if written != json_out else None
    return result, fallback, checked


def write_pictures(
    problem: Problem,
    result: PlanResult,
    settings: RunSettings,
    gif: Path | None,
    html: Path | None,
    *,
    gif_size: int | None = None,
    quiet: bool = False,
) -> None:
    """The ``--gif`` animation (views of ``gif_size`` pixels; None: the default) and the
    ``--html`` page of a solve's result. Each is its own file: a failed animation (a full
    disk) still leaves the page written, then raises."""
    failed: StalmError | None = None
    if gif is not None:
        try:
            write_gif(problem, result, gif, gif_size, quiet)
        except StalmError as error:
            failed = error  # raised once the page is written (main prints it)
    if html is not None:
        from stalm.cli import view_commands

        view_commands.write_view_page(problem, result_record(result, problem, settings), html)
    if failed is not None:
        raise failed


def write_gif(
    problem: Problem,
    result: PlanResult,
    path: Path,
    size: int | None = None,
    quiet: bool = False,
) -> None:
    """``--gif``: the animation of a solve's plan (:func:`write_plan_gif`)."""
    pairs = list(zip(result.plan, result.states[1:], strict=True))
    write_plan_gif(problem, result.states[0], pairs, path, size, quiet)


def write_plan_gif(
    problem: Problem,
    start: State,
    pairs: list[tuple[Action, State]],
    path: Path,
    size: int | None = None,
    quiet: bool = False,
) -> None:
    """The animation of ``pairs`` (an action and the state it leads to) from ``start``,
    with the frames rendered so far shown on a terminal (unless ``quiet``)."""
    from stalm.cli.solve_progress import solve_progress
    from stalm.viz.animate import write_animation
    from stalm.viz.sizes import GIF_SIZE
    from stalm.world.scene import Sim

    with (
        Sim(problem.spec) as sim,
        solve_progress(console, "rendering the animation...", quiet) as observer,
    ):
        try:
            frames = write_animation(
                sim, start, pairs, path, size or GIF_SIZE, progress=observer.frames
            )
        except OSError as error:
            raise StalmError(f"--gif {path}: cannot write it ({error.strerror})") from None
    out.print(f"wrote {shown(path)} ({frames} frames)", highlight=False)
