"""Task-plan proposers: where a batch of task plans comes from.

The paper's proposer is a language model queried with the predicate prompt (§3.2–3.3):
:class:`LLMProposer` builds the prompt for the current state, asks the backend for N_batch
replies at temperature 1, and parses each reply into a task plan, keeping unparseable replies
as data with their reason.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from stalm.domain.actions import DiscreteAction
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.backends.base import LLMBackend, LLMRequest
from stalm.llm.constraints import build_constraint, json_reply_to_plan_text
from stalm.llm.feedback_prompt import with_feedback
from stalm.llm.problem_prompt import problem_prompt
from stalm.llm.prompt import Prompt, PromptOptions
from stalm.llm.reply_parser import parse_reply
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.feedback import FailedStep
from stalm.world.problem import Problem
from stalm.world.state import State

MAX_REPLY_TOKENS = 500
"""The token budget of one reply (the authors' max_tokens)."""


@dataclass(frozen=True)
class Proposal:
    """A batch of task plans, the replies they came from, and what asking cost.

    ``truncated[i]`` says plan ``i`` is only the beginning of its reply's plan: the reply was
    cut off inside the plan list (by ``max_tokens``) and its complete steps were kept, as the
    authors' parser did. It is aligned with ``plans``, or empty from a proposer whose plans are
    never cut (the symbolic one).

    ``seconds`` is the wall time the query took now. ``from_cache`` is true when every reply
    came from the reply cache; ``cached_seconds`` is what the calls that first produced the
    cached replies took (the cache stores it), so :attr:`original_seconds` is the time of the
    run a replay reproduces, whatever happened to be cached when it ran.
    """

    plans: tuple[tuple[DiscreteAction, ...], ...]
    unparseable: tuple[str, ...] = ()
    """Per model reply that could not be read: the parser's reason."""
    no_plan: tuple[str, ...] = ()
    """Why a planning proposer (no model: the symbolic one) found no plan; Figure 5 counts it
    as ``no_plan``, not as an unreadable reply."""
    replies: tuple[str, ...] = ()
    calls: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    seconds: float = 0.0
    from_cache: bool = False
    truncated: tuple[bool, ...] = ()
    cached_seconds: float = 0.0
    injected: tuple[str, ...] = ()
    """Per plan, what a degraded proposer did to it on purpose (:mod:`stalm.proposers.noisy`:
    ``clean``, ``inapplicable`` or the Figure 5 kind it injected); empty from every other
    proposer."""
    set_aside: tuple[str, ...] = ()
    """The predicate literals the plans were made without, as text: the symbolic proposer's
    occlusion cycles (:mod:`stalm.proposers.occlusion_cycles`) when the abstraction had no
    plan with them; empty from every other proposer."""

    @property
    def truncated_plans(self) -> int:
        """How many of ``plans`` are the kept beginning of a reply cut off inside its plan."""
        return sum(self.truncated)

    @property
    def original_seconds(self) -> float:
        """The seconds this query took when its replies were made: the stored seconds of cached
        replies plus, for replies made now, the time taken now (all of it when nothing came
        from the cache; only the stored seconds when everything did)."""
        return self.cached_seconds + (0.0 if self.from_cache else self.seconds)


class TaskPlanProposer(Protocol):
    """Anything that proposes task plans for a state given its predicates."""

    @property
    def name(self) -> str: ...

    def propose(
        self,
        problem: Problem,
        state: State,
        literals: Iterable[GroundLiteral],
        n: int,
        seed: int,
        deadline: float | None = None,
    ) -> Proposal:
        """Up to ``n`` task plans from ``state``; stop early at ``deadline`` (monotonic).

        A proposer that can use geometric feedback is a :class:`FeedbackProposer`. STaLM
        passes ``feedback=`` only when feedback is switched on and there is some, so a
        proposer written without it keeps working.
        """
        ...


class FeedbackProposer(TaskPlanProposer, Protocol):
    """A proposer that also takes the failed steps that hold in ``state``
    (:class:`stalm.proposers.feedback.FailedStep`) and avoids them."""

    def propose(
        self,
        problem: Problem,
        state: State,
        literals: Iterable[GroundLiteral],
        n: int,
        seed: int,
        deadline: float | None = None,
        feedback: Sequence[FailedStep] = (),
    ) -> Proposal: ...


def takes_feedback(proposer: TaskPlanProposer) -> bool:
    """Whether ``proposer.propose`` accepts ``feedback=`` (a :class:`FeedbackProposer`)."""
    return "feedback" in inspect.signature(proposer.propose).parameters


@dataclass
class LLMProposer:
    """Task plans from a language model queried with the paper's prompt."""

    backend: LLMBackend
    options: PromptOptions = field(default_factory=PromptOptions)
    temperature: float = 1.0
    max_tokens: int = MAX_REPLY_TOKENS
    constrained: bool = False

    @property
    def name(self) -> str:
        return f"llm:{self.backend.name}:{self.backend.model}"

    def propose(
        self,
        problem: Problem,
        state: State,
        literals: Iterable[GroundLiteral],
        n: int,
        seed: int,
        deadline: float | None = None,
        feedback: Sequence[FailedStep] = (),
    ) -> Proposal:
        """The paper's query; with ``feedback`` (``--feedback``, beyond the paper) the failed
        steps are appended to the prompt as Iterative-Replanning's feedback is."""
        prompt = problem_prompt(problem, literals, self.options)
        if feedback:
            prompt = with_feedback(prompt, [step.as_failed_plan() for step in feedback])
        return ask_for_task_plans(
            self.backend,
            Vocabulary.from_problem(problem),
            prompt,
            n,
            seed,
            constrained=self.constrained,
            temperature=self.temperature,
            max_tokens=self.max_tokens,
            deadline=deadline,
        )


def ask_for_task_plans(
    backend: LLMBackend,
    vocabulary: Vocabulary,
    prompt: Prompt,
    n: int,
    seed: int,
    *,
    constrained: bool,
    temperature: float = 1.0,
    max_tokens: int = MAX_REPLY_TOKENS,
    deadline: float | None = None,
) -> Proposal:
    """Send ``prompt`` once for ``n`` replies and parse each into a task plan.

    STaLM and the baselines that write their own prompt (SayCan's instruction and history,
    Iterative-Replanning's feedback) all read replies here: the same template, parser and
    output constraint, so no method is better or worse merely for parsing differently. Every
    reply is kept: a readable one as a plan (its valid prefix), an unreadable one as its reason
    in ``unparseable``. Replies cut off by ``deadline`` are dropped: they are not the model's
    answer. A reply cut by ``max_tokens`` inside its plan keeps its complete steps and is
    marked in ``truncated``. The output constraint follows the prompt: it demands the
    challenges section only when the prompt asks for it (Table 4's ablations).
    """
    constraint = (
        build_constraint(vocabulary, challenges=prompt.asks_challenges) if constrained else None
    )
    request = LLMRequest(
        system=prompt.system,
        user=prompt.user,
        n=n,
        temperature=temperature,
        max_tokens=max_tokens,
        seed=seed,
        constraint=constraint,
        deadline=deadline,
    )
    start = time.perf_counter()
    response = backend.complete(request)
    seconds = time.perf_counter() - start
    plans: list[tuple[DiscreteAction, ...]] = []
    truncated: list[bool] = []
    unparseable: list[str] = []
    for reply in response.replies:
        if reply.finish_reason == "deadline":
            continue
        text = reply.text
        if constrained and text.lstrip().startswith("{"):
            # structured-output servers answer the JSON-schema form; read it as the template
            try:
                text = json_reply_to_plan_text(text)
            except StalmError as error:
                unparseable.append(str(error))
                continue
        parsed = parse_reply(text, vocabulary)
        if parsed.plan:
            plans.append(tuple(parsed.plan))
            truncated.append(parsed.truncated)
        else:
            unparseable.append(parsed.reason or "no plan in the reply")
    return Proposal(
        plans=tuple(plans),
        unparseable=tuple(unparseable),
        replies=response.texts,
        calls=1,
        prompt_tokens=response.prompt_tokens,
        completion_tokens=response.completion_tokens,
        seconds=seconds,
        from_cache=response.from_cache,
        truncated=tuple(truncated),
        cached_seconds=response.cached_seconds,
    )
