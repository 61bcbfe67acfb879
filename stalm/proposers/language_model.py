"""The paper's task-plan proposer (§3.2–3.3): :class:`LLMProposer` asks a language model with
the predicate prompt of the current state for N_batch replies at temperature 1, and parses
each reply into a task plan, keeping unparseable replies as data with their reason."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from stalm.domain.actions import DiscreteAction
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.backends.base import LLMBackend, LLMRequest
from stalm.llm.constraints import build_constraint, json_reply_to_plan_text
from stalm.llm.feedback_prompt import with_feedback
from stalm.llm.problem_prompt import problem_prompt
from stalm.llm.prompt import Prompt, PromptOptions
from stalm.llm.reply_parser import parse_reply
from stalm.proposers.model_backend import llm_backend, use_constraint
from stalm.proposers.protocol import Proposal, ProposalRequest
from stalm.settings.tree import RunSettings

MAX_REPLY_TOKENS = 500
"""The token budget of one reply (the authors' max_tokens)."""


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

    @property
    def takes_feedback(self) -> bool:
        return True

    def propose(self, request: ProposalRequest) -> Proposal:
        """The paper's query; with feedback (``--feedback``, beyond the paper) the failed
        steps are appended to the prompt as Iterative-Replanning's feedback is."""
        problem = request.problem
        prompt = problem_prompt(problem, request.literals, self.options)
        if request.feedback:
            prompt = with_feedback(prompt, [step.as_failed_plan() for step in request.feedback])
        return ask_for_task_plans(
            self.backend,
            Vocabulary.from_problem(problem),
            prompt,
            request.n,
            request.seed,
            constrained=self.constrained,
            temperature=self.temperature,
            max_tokens=self.max_tokens,
            deadline=request.deadline,
        )


def model_proposer(settings: RunSettings) -> LLMProposer:
    """The language model the settings name (behind its reply cache), asked with their prompt."""
    backend = llm_backend(settings)
    return LLMProposer(backend, settings.prompt, constrained=use_constraint(settings, backend))


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
