"""``stalm predicates``, ``stalm prompt`` and ``stalm parse-reply``: what the model is told, and
what it answered, for a problem."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from stalm.cli.display import printable
from stalm.cli.text_commands import format_parsed_reply_json, format_prompt, parse_reply_file
from stalm.cli.world_commands import read_state_file
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.problem_prompt import ordered_literals, problem_prompt
from stalm.llm.prompt import PromptOptions, cannot_action
from stalm.predicates.literals import CANNOT_PREDICATES, SCOPE_PREDICATE, GroundLiteral
from stalm.world.problem import Problem, load_problem

commands = typer.Typer()
"""The top-level commands this module adds; :mod:`stalm.cli.main` composes them."""

console = Console()

ProblemArg = Annotated[str, typer.Argument(help="Problem name (P5) or path to a problem file.")]
StateOpt = Annotated[
    Path | None, typer.Option("--state", help="Use this State (JSON) instead of the initial one.")
]
RelevantOpt = Annotated[
    bool,
    typer.Option(
        "--relevant-only",
        help="Occlusions only of the goal's objects and, recursively, what blocks them "
        "(predicates.relevant_only; beyond the paper).",
    ),
]


def compute_literals(
    problem: Problem, state_file: Path | None, relevant_only: bool = False
) -> list[GroundLiteral]:
    """The predicates of the problem's initial state (or of a given State), in prompt order;
    with ``relevant_only``, occlusions only where a plan must act (``predicates.relevant_only``)."""
    from stalm.motion.base_motion import BasePlanner
    from stalm.predicates.engine import PredicateEngine
    from stalm.predicates.samples import PredicateSettings
    from stalm.world.scene import Sim

    state = (
        read_state_file(state_file, problem) if state_file is not None else problem.initial_state
    )
    with Sim(problem.spec) as sim, console.status("computing predicates (motion planning)..."):
        settings = PredicateSettings(relevant_only=relevant_only)
        engine = PredicateEngine(problem, sim, BasePlanner(sim), settings)
        cache = engine.compute(state)
    return ordered_literals(problem, cache.literals)


@commands.command("predicates")
def predicates_command(
    problem: ProblemArg,
    state_file: StateOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON tuples.")] = False,
    relevant_only: RelevantOpt = False,
) -> None:
    """Print the geometric predicates (occlusions computed by motion planning) of a state."""
    loaded = load_problem(problem)
    literals = compute_literals(loaded, state_file, relevant_only)
    if as_json:
        typer.echo(json.dumps([list(lit.as_tuple()) for lit in literals], indent=1))
        return
    cannot = [lit for lit in literals if lit.name in CANNOT_PREDICATES]
    scope = sorted(lit.args[0] for lit in literals if lit.name == SCOPE_PREDICATE)
    for literal in literals:
        if literal.name not in CANNOT_PREDICATES and literal.name != SCOPE_PREDICATE:
            typer.echo(printable(literal))
    for literal in cannot:  # actions no motion can do: the paper's prompt does not show them
        typer.echo(printable(f"cannot: {cannot_action(literal)}"))
    if scope:  # relevance-limited: the other objects' occlusions were not computed
        typer.echo(printable(f"occlusion computed for: {', '.join(scope)}"))
    shown_count = len(literals) - len(cannot) - len(scope)
    typer.echo(f"# {shown_count} literals, {len(cannot)} cannot", err=True)


@commands.command("prompt")
def prompt_command(
    problem: ProblemArg,
    state_file: StateOpt = None,
    no_occlusion: Annotated[
        bool, typer.Option("--no-occlusion", help="Ablation: leave out the occlusion predicates.")
    ] = False,
    no_challenges: Annotated[
        bool, typer.Option("--no-challenges", help="Ablation: do not ask for the challenges.")
    ] = False,
    relevant_only: RelevantOpt = False,
) -> None:
    """Print the paper's prompt (system and user message, Figure 13 format) for a problem."""
    loaded = load_problem(problem)
    literals = compute_literals(loaded, state_file, relevant_only)
    options = PromptOptions(occlusion_predicates=not no_occlusion, ask_challenges=not no_challenges)
    if no_occlusion:
        literals = [
            lit for lit in literals if lit.name not in ("PickOccludedBy", "PlaceOccludedBy")
        ]
    typer.echo(printable(format_prompt(problem_prompt(loaded, literals, options))))


@commands.command("parse-reply")
def parse_reply_command(
    reply: Annotated[Path, typer.Argument(help="A text file holding a model's reply.")],
    problem: Annotated[str, typer.Option("--problem", "-p", help="The problem it answers.")],
) -> None:
    """Print the task plan read from a reply, and every step error, as JSON."""
    loaded = load_problem(problem)
    parsed = parse_reply_file(reply, Vocabulary.from_problem(loaded))
    typer.echo(format_parsed_reply_json(parsed))
