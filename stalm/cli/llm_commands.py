"""``stalm llm ...``: see which language model stalm would use, and that it answers.

A planning run that fails on its first LLM call after minutes of setup is a poor way to learn
that a key is wrong or a server is down; ``stalm llm check`` asks one short question and
reports backend, model, latency and token counts in a few seconds.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Annotated

import typer
from rich.console import Console
from rich.panel import Panel

from stalm.cli.display import shown
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.backends import (
    SPEC_ENV,
    SPEC_HELP,
    LLMReply,
    LLMRequest,
    LLMResponse,
    OpenAICompatibleBackend,
    make_backend,
)
from stalm.llm.backends.constraint_styles import (
    CONSTRAINT_STYLE_ENV,
    CONSTRAINT_STYLES,
    ConstraintRefused,
    both_refused,
    check_constraint_style,
)
from stalm.llm.backends.retries import DeadlinePassed
from stalm.llm.constraints import build_constraint

llm_app = typer.Typer(
    name="llm",
    help="Check the language-model backend stalm uses.",
    no_args_is_help=True,
    add_completion=False,
)


@llm_app.callback()
def _llm_group() -> None:
    """Check the language-model backend stalm uses."""


_CHECK_SYSTEM = "You are a helpful assistant. Answer in one short sentence."
_CONSTRAINED_SYSTEM = (
    "You are an expert proficient in PDDL and planning actions for a problem. Your response "
    "should follow this template:\n## Possible Challenges for unachieved goals based on "
    "current state ##\n\n## Plan for unachieved goals ## plan = [('action_type', 'args_1', "
    "'args_2',...), ]"
)
_CONSTRAINED_USER = (
    "Objects: coke - movable_object, counter1 counter2 - region, kitchen_door - openable.\n"
    "Init: (AtPosition coke on counter1) (IsClosed kitchen_door) (PickOccludedBy coke "
    "kitchen_door)\nGoal: (AtPosition coke on counter2)\n"
    "Generate a plan to achieve the goals from init."
)
_CONSTRAINED_VOCABULARY = Vocabulary(
    movables=("coke",), regions=("counter1", "counter2"), doors=("kitchen_door",)
)


@llm_app.command("check")
def check(
    llm: Annotated[
        str | None,
        typer.Option("--llm", envvar=SPEC_ENV, help=f"Backend spec: {SPEC_HELP}."),
    ] = None,
    prompt: Annotated[
        str, typer.Option(help="The question to ask.")
    ] = "In one sentence: what does a robot need to do before picking up an occluded object?",
    max_tokens: Annotated[int, typer.Option(help="Reply length limit in tokens.")] = 48,
    timeout: Annotated[
        float, typer.Option(help="Seconds to wait for the answer, retries included.")
    ] = 60.0,
    seed: Annotated[int, typer.Option(help="Sampling seed.")] = 0,
    constrained: Annotated[
        bool,
        typer.Option(
            "--constrained",
            help="Ask for a tiny plan under the reply grammar/schema instead, to check that "
            "the server accepts output constraints; a server given by URL is asked in each "
            "style (json_schema, gbnf), and told which one to set.",
        ),
    ] = False,
) -> None:
    """Show the configured backend and model, then time one short answer."""
    console = Console()
    if not (math.isfinite(timeout) and timeout > 0):
        raise StalmError(f"--timeout must be a positive number of seconds, got {timeout}")
    backend = make_backend(llm)
    console.print(f"[bold]backend[/]: {shown(backend.name)}", highlight=False)
    console.print(f"[bold]model[/]:   {shown(backend.model)}", highlight=False)
    notice_style = "yellow" if backend.name == "embedded" else "blue"
    console.print(Panel(shown(backend.description), border_style=notice_style, title="about"))
    if constrained:
        request = LLMRequest(
            system=_CONSTRAINED_SYSTEM,
            user=_CONSTRAINED_USER,
            n=1,
            temperature=0.0,
            max_tokens=max(max_tokens, 512),
            seed=seed,
            constraint=build_constraint(_CONSTRAINED_VOCABULARY),
            deadline=time.monotonic() + timeout,
        )
    else:
        request = LLMRequest(
            system=_CHECK_SYSTEM,
            user=prompt,
            n=1,
            temperature=0.0,
            max_tokens=max_tokens,
            seed=seed,
            deadline=time.monotonic() + timeout,
        )
    if constrained and isinstance(backend, OpenAICompatibleBackend):
        response = _check_constraint_styles(console, backend, request)
    else:
        with console.status("asking the model..."):
            response = backend.complete(request)
    if not response.replies or response.replies[0].finish_reason == "deadline":
        raise StalmError(f"{backend.name} model {backend.model!r}: no answer within {timeout:g} s")
    reply = response.replies[0]
    console.print(Panel(shown(reply.text.strip()) or "(empty reply)", title="reply"))
    rate = reply.completion_tokens / reply.latency_s if reply.latency_s > 0 else 0.0
    console.print(
        f"latency {reply.latency_s:.2f} s | prompt tokens {reply.prompt_tokens} | "
        f"completion tokens {reply.completion_tokens} | {rate:.1f} tokens/s | "
        f"finish: {shown(reply.finish_reason or '?')}"
    )


def _check_constraint_styles(
    console: Console, backend: OpenAICompatibleBackend, request: LLMRequest
) -> LLMResponse:
    """Send the constrained question in each style; say which the server takes and what to
    set. The configured style's answer if it was taken, else the other's; a StalmError if the
    server takes neither."""
    configured = backend.constraint_style
    order = [configured] + [s for s in CONSTRAINT_STYLES if s != configured]
    answers: dict[str, list[LLMReply]] = {}
    refusals: list[ConstraintRefused] = []
    window = request.deadline - time.monotonic() if request.deadline is not None else None
    for style in order:
        # each style gets the whole timeout: a slow answer to the first must not leave the
        # second none
        styled = request
        if window is not None:
            styled = dataclasses.replace(request, deadline=time.monotonic() + window)
        with console.status(f"asking the model with the constraint as {style}..."):
            try:
                answers[style] = backend.send(
                    styled,
                    backend.model,
                    1,
                    request.seed,
                    check_constraint_style(style),
                    refusable=True,
                )
            except ConstraintRefused as refused:
                refusals.append(refused)
                console.print(f"[red]refused[/]  {shown(str(refused))}", highlight=False)
            except DeadlinePassed:
                console.print(f"[red]no answer in time[/] {style}", highlight=False)
            else:
                console.print(f"[green]accepted[/] {style}", highlight=False)
    if not answers and len(refusals) == len(order):
        raise both_refused(backend.url, refusals[0], refusals[1])
    if not answers:
        raise StalmError(
            f"{backend.url}: no answer within the timeout in any style it did not refuse"
        )
    taken = configured if configured in answers else next(iter(answers))
    if taken == configured:
        console.print(f"this server takes the configured style, {configured}", highlight=False)
    else:
        console.print(
            f"[yellow]this server takes {taken}, not {configured}:[/] set "
            f"{CONSTRAINT_STYLE_ENV}={taken} (a run switches by itself, with a notice)",
            highlight=False,
        )
    return LLMResponse(tuple(answers[taken]), backend.name, backend.model)
