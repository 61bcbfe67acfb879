"""``stalm experiment`` (run a paper table's trials, resumably) and ``stalm report``."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from stalm.cli.display import printable, shown
from stalm.cli.settings_options import SET_HELP, SETTINGS_HELP, command_settings, given
from stalm.errors import StalmError
from stalm.stopping import Stopped, stop_code, stop_message
from stalm.temp_folders import remove_leftovers

if TYPE_CHECKING:
    from stalm.experiments.trials import Arm

commands = typer.Typer()
"""The top-level commands this module adds; :mod:`stalm.cli.main` composes them."""

console = Console(stderr=True)
out = Console()


def _names(text: str | None) -> tuple[str, ...] | None:
    if not text:
        return None
    return tuple(part.strip() for part in text.split(",") if part.strip())


def _rates(text: str | None) -> tuple[float, ...] | None:
    """``--rates 0,0.25,0.5`` as numbers (their range is the experiment plan's to check)."""
    names = _names(text)
    if names is None:
        return None
    try:
        return tuple(float(name) for name in names)
    except ValueError:
        raise StalmError(f"--rates must be comma-separated numbers, got {text!r}") from None


@commands.command("experiment")
def experiment_command(
    name: Annotated[
        str,
        typer.Argument(
            help="table2, table3, table4, figure5, scale (with --suite), or additions (STaLM "
            "on the noisy proposer with each of this implementation's additions to the tree "
            "left out alone; P3-P6 by default)."
        ),
    ],
    problems: Annotated[
        str | None, typer.Option(help="Comma-separated problems (default P1..P6).")
    ] = None,
    planners: Annotated[
        str | None,
        typer.Option(
            help="Comma-separated rows: the paper's methods by planner name (see `stalm "
            "planners`), run as the authors ran them; NAME+ (uct+, uct-hcount+, stalm+, ...) for "
            "the same with this implementation's additions; stalm-symbolic (STaLM with the "
            "Fast Downward proposer). Default: the paper's rows."
        ),
    ] = None,
    trials: Annotated[int, typer.Option(help="Trials per problem and planner.")] = 50,
    llm: Annotated[
        list[str] | None,
        typer.Option(help="Model for the model-based rows; repeat it for table3's two models."),
    ] = None,
    suite: Annotated[
        Path | None,
        typer.Option(help="scale: the folder of a generated suite (stalm generate --suite)."),
    ] = None,
    proposer: Annotated[
        str | None,
        typer.Option(
            "--proposer",
            help="Where STaLM's task plans come from (proposer.kind): llm, symbolic, or noisy "
            "(a degraded proposer, no language model: Fast Downward's plans corrupted on "
            "purpose at the rate proposer.noise.rate; table3 then runs STaLM and STaLM w/o UCT "
            "at every --rates, and UCT once).",
        ),
    ] = None,
    rates: Annotated[
        str | None,
        typer.Option(
            help="With --proposer noisy: comma-separated error rates in [0, 1], one row per "
            "rate (default: proposer.noise.rate, 0.5).",
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Master seed; trial seeds derive from it.")] = 0,
    budget_scale: Annotated[
        float, typer.Option(help="Multiply the paper's time budgets (300/600 s) by this.")
    ] = 1.0,
    time_budget: Annotated[
        float | None, typer.Option("--time-budget", help="One budget (s) for every problem.")
    ] = None,
    sims: Annotated[
        int | None, typer.Option(help="N_budget (search.sims; default: the paper's).")
    ] = None,
    workers: Annotated[
        int,
        typer.Option(
            help="Trials run at once, one process each (at most the cores this process may use)."
        ),
    ] = 1,
    ray: Annotated[
        str | None,
        typer.Option("--ray", help="Run on a Ray cluster: 'auto', 'ray://host:10001' or 'local'."),
    ] = None,
    cache: Annotated[
        str | None,
        typer.Option(help="Reply cache mode (llm.cache): use (default), refresh, off, replay."),
    ] = None,
    results: Annotated[
        Path | None,
        typer.Option(
            help="The JSON-lines results file (default results/NAME.jsonl; "
            "results/table3-noisy.jsonl for table3 with --proposer noisy)."
        ),
    ] = None,
    report_dir: Annotated[
        Path | None, typer.Option(help="Write the report here when done (default: beside).")
    ] = None,
    settings_file: Annotated[
        Path | None,
        typer.Option("--settings", help=SETTINGS_HELP + " A row's own settings still win."),
    ] = None,
    overrides: Annotated[
        list[str] | None,
        typer.Option("--set", help=SET_HELP + " For every row; a row's own settings still win."),
    ] = None,
    physics: Annotated[
        bool,
        typer.Option(
            "--physics",
            help="Settle each solved plan under gravity (as stalm replay --physics) and record "
            "the check in its trial's record as 'physics'.",
        ),
    ] = False,
    robot: Annotated[
        str | None,
        typer.Option(
            "--robot",
            help="Run every trial with this robot (a built-in one, `stalm robot list`, or a "
            "robot file) in place of the problem's; records name it as 'robot'. Give each "
            "robot its own --results file.",
        ),
    ] = None,
) -> None:
    """Run a paper experiment's trials; re-running the same command resumes it."""
    from stalm.cores import check_process_count
    from stalm.experiments.results_log import ResultsLog
    from stalm.experiments.runner import run_experiment
    from stalm.experiments.suites import build_plan, trial_specs

    check_process_count("--workers", workers)  # the runner checks too: here before any work
    flags = given(
        sims=("search.sims", sims), cache=("llm.cache", cache), proposer=("proposer.kind", proposer)
    )
    base = command_settings(settings_file, flags, overrides or ()).settings
    plan = build_plan(
        name,
        planners=_names(planners),
        problems=_names(problems),
        trials=trials,
        llms=tuple(llm or ()),
        master_seed=seed,
        budget_scale=budget_scale,
        time_budget_s=time_budget,
        base=base,
        suite=suite,
        rates=_rates(rates),
    )
    _check_model_rows(plan.arms)
    specs = trial_specs(plan)
    if physics:
        specs = [dataclasses.replace(spec, physics=True) for spec in specs]
    if robot is not None:
        from stalm.experiments.trials import for_robot

        specs = [for_robot(spec, robot) for spec in specs]
    # the noisy proposer's Table 3 is a table of its own, not rows added to the model's
    stem = f"{name}-noisy" if name == "table3" and base.proposer.kind == "noisy" else name
    path = results or Path("results") / f"{stem}.jsonl"
    with _one_writer(path):
        log = ResultsLog(path)
        if log.set_aside is not None:
            console.print(
                f"[yellow]warning:[/] {shown(log.path)}: moved its partial last line to "
                f"{shown(log.set_aside)}",
                highlight=False,
                soft_wrap=True,
            )
        loaded = log.load()
        for problem in loaded.problems:
            console.print(f"[yellow]warning:[/] {shown(problem)}", highlight=False, soft_wrap=True)
        finished = loaded.finished_keys()
        done_before = sum(spec.key in finished for spec in specs)
        rows = ", ".join(arm.label for arm in plan.arms)
        console.print(
            f"{name}: {len(specs)} trials ({rows} on {', '.join(plan.problems)}, {plan.trials} "
            f"each); {done_before} already in {log.path}",
            highlight=False,
        )
        solved = 0
        ran = 0
        started = time.monotonic()
        with Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("solved {task.fields[solved]}"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            console=console,
            transient=False,
        ) as progress:
            task = progress.add_task(name, total=len(specs) - done_before, solved=0)

            def on_record(record: dict[str, Any]) -> None:
                nonlocal solved, ran
                ran += 1
                solved += bool(record.get("success"))
                progress.update(task, advance=1, solved=f"{solved}/{ran}")
                status = "solved" if record.get("success") else shown(record.get("termination"))
                if record.get("termination") == "error":
                    status = "[red]error[/]: " + shown(record.get("error"))
                progress.console.print(
                    f"{shown(record['arm'])} {shown(record['problem'])} trial {record['trial']}: "
                    f"{status} "
                    f"in {float(record.get('time_s', 0.0)):.1f} s",
                    highlight=False,
                )
                if record.get("termination") == "error":
                    errors.append(f"{record['arm']} {record['problem']}: {record.get('error')}")

            errors: list[str] = []
            try:
                summary = run_experiment(
                    specs, log, workers=workers, ray_address=ray, on_record=on_record
                )
            except (KeyboardInterrupt, Stopped) as stop:
                remove_leftovers(mine_too=True)  # one the signal cut off before its ``try``
                console.print(
                    f"[yellow]{stop_message(stop)}:[/] {ran} trials saved in {log.path}; run "
                    "the same command to resume",
                    highlight=False,
                )
                raise typer.Exit(stop_code(stop)) from None
    console.print(
        f"ran {summary.ran} trials ({summary.solved} solved, {summary.errors} errors) in "
        f"{time.monotonic() - started:.0f} s; {summary.skipped} were already done",
        highlight=False,
    )
    _report([log.path], report_dir or log.path.parent, log.path.stem, paper=name == "table2")
    if errors:
        console.print(
            f"[red]{len(errors)} trials ended in an error[/] (a re-run retries them); the "
            f"first: {shown(errors[0])}",
            highlight=False,
        )
        raise typer.Exit(1)


@contextmanager
def _one_writer(path: Path) -> Iterator[None]:
    """Hold the results file's lock for the block; another run holding it ends this command
    with exit code 1 and one line naming that run (see :mod:`stalm.experiments.results_lock`)."""
    from stalm.experiments.results_lock import ResultsBusy, results_lock

    try:
        with results_lock(path):
            yield
    except ResultsBusy as error:  # raised only on entering: another run holds the file
        console.print(f"[bold red]error:[/] {shown(error)}", highlight=False, soft_wrap=True)
        raise typer.Exit(1) from None


def _check_model_rows(arms: Sequence[Arm]) -> None:
    """Refuse before any trial when a row that asks a model cannot have one (the embedded
    model without its install extra): one line naming the rows, not an error mid-run."""
    from stalm.llm.backends import make_backend
    from stalm.planners.registry import asks_model

    for arm in arms:
        if not asks_model(arm.planner, arm.config):
            continue
        try:
            make_backend(arm.config.llm.backend)  # no model is loaded here
        except StalmError as error:
            needing = [a.label for a in arms if asks_model(a.planner, a.config)]
            raise StalmError(
                f"the rows {', '.join(needing)} ask a language model: {error} (or leave them "
                "out with --planners)"
            ) from None


def read_results(paths: Sequence[Path]) -> list[dict[str, Any]]:
    """The records of results files, each warning (a record that cannot be read, a partial
    last line) printed; a missing file, or none holding a record, is a StalmError."""
    from stalm.experiments.results_log import read_records

    records: list[dict[str, Any]] = []
    for path in paths:
        if not path.exists():
            raise StalmError(f"no results file at {path}")
        loaded = read_records(path)
        for problem in loaded.problems:
            console.print(f"[yellow]warning:[/] {shown(problem)}", highlight=False, soft_wrap=True)
        if loaded.skipped_partial_line:
            console.print(
                f"[yellow]warning:[/] {shown(path)}: skipped a partial last line",
                highlight=False,
                soft_wrap=True,
            )
        records += loaded.records
    if not records:
        raise StalmError(f"no trial records in {', '.join(str(p) for p in paths)}")
    return records


def _report(paths: list[Path], out_dir: Path, name: str, *, paper: bool) -> None:
    from stalm.experiments.report import write_report

    records = read_results(paths)
    text, files = write_report(records, out_dir, name=name, paper=paper)
    for note in files.left_out:
        console.print(f"[yellow]warning:[/] {shown(note)}", highlight=False, soft_wrap=True)
    out.print(printable(text), highlight=False, markup=False, soft_wrap=True)
    written = [files.markdown, files.csv, *files.plots]
    console.print("wrote " + ", ".join(shown(p) for p in written), highlight=False)


@commands.command("report")
def report_command(
    results: Annotated[list[Path], typer.Argument(help="JSON-lines results files.")],
    out_dir: Annotated[
        Path | None, typer.Option("--out", help="Folder for the .md, .csv and plots.")
    ] = None,
    name: Annotated[str | None, typer.Option(help="Base name of the files written.")] = None,
    paper: Annotated[
        bool, typer.Option("--paper/--no-paper", help="Show the paper's Table 2 numbers beside.")
    ] = False,
) -> None:
    """Print the tables of finished trials like the paper's; save Markdown, CSV and plots."""
    first = results[0]
    _report(results, out_dir or first.parent, name or first.stem, paper=paper)
