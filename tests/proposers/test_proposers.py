"""The LLM proposer: prompt in, parsed task plans and unparseable replies out."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.backends.base import LLMReply, LLMRequest, LLMResponse
from stalm.llm.constraints import CHALLENGES_HEADER, build_constraint
from stalm.llm.prompt import PromptOptions
from stalm.llm.saycan_prompt import saycan_prompt
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.language_model import LLMProposer, ask_for_task_plans
from stalm.proposers.protocol import ProposalRequest


@dataclass
class CannedRepliesBackendDouble:
    """Test double: answers every request with fixed reply texts, recording the requests."""

    texts: tuple[str, ...]
    name: str = "double"
    model: str = "canned"
    description: str = "test double"

    def __post_init__(self) -> None:
        self.requests: list[LLMRequest] = []

    def complete(self, request: LLMRequest) -> LLMResponse:
        self.requests.append(request)
        replies = tuple(
            LLMReply(self.texts[i % len(self.texts)], 100 if i == 0 else 0, 20, 0.01)
            for i in range(request.n)
        )
        return LLMResponse(replies, self.name, self.model)


def test_replies_become_task_plans_and_reasons(problems) -> None:
    backend = CannedRepliesBackendDouble(
        (
            "## Plan ##\nplan = [('pick', 'bottle2'), ('place', 'bottle2', 'on', 'counter1')]",
            "I cannot help with that.",
            '{"challenges": "none", "plan": [["pick", "salter"]]}',
        )
    )
    proposer = LLMProposer(backend)
    literals = [GroundLiteral("HandAvailable")]
    proposal = proposer.propose(
        ProposalRequest(
            problems["P2"], problems["P2"].initial_state, frozenset(literals), 3, seed=9
        )
    )
    assert proposal.plans == ((Pick("bottle2"), Place("bottle2", "on", "counter1")),)
    assert len(proposal.unparseable) == 2 and proposal.calls == 1
    assert proposal.prompt_tokens == 100 and proposal.completion_tokens == 60
    request = backend.requests[0]
    assert request.n == 3 and request.seed == 9 and request.temperature == 1.0
    assert request.max_tokens == 500 and request.constraint is None
    assert "('HandAvailable', '')" in request.user
    assert proposer.name == "llm:double:canned"


def test_constrained_json_replies_are_read_as_the_template(problems) -> None:
    backend = CannedRepliesBackendDouble(
        ('{"challenges": "none", "plan": [["pick", "salter"]]}', "{not json")
    )
    proposer = LLMProposer(backend, constrained=True)
    proposal = proposer.propose(
        ProposalRequest(problems["P2"], problems["P2"].initial_state, frozenset(), 2, seed=0)
    )
    assert proposal.plans == ((Pick("salter"),),)
    assert len(proposal.unparseable) == 1
    assert backend.requests[0].constraint is not None


@pytest.mark.parametrize("challenges", [True, False])
def test_the_output_constraint_follows_the_prompts_challenges_option(
    problems, challenges: bool
) -> None:
    backend = CannedRepliesBackendDouble(("plan = [('pick', 'salter')]",))
    options = PromptOptions(ask_challenges=challenges)
    proposer = LLMProposer(backend, options, constrained=True)
    proposer.propose(
        ProposalRequest(problems["P2"], problems["P2"].initial_state, frozenset(), 1, seed=0)
    )
    constraint = backend.requests[0].constraint
    assert constraint is not None
    vocabulary = Vocabulary.from_problem(problems["P2"])
    assert constraint == build_constraint(vocabulary, challenges=challenges)
    assert (CHALLENGES_HEADER in constraint.gbnf) is challenges
    assert ("challenges" in constraint.json_schema()["required"]) is challenges


def test_saycan_prompt_never_asks_for_challenges_nor_does_its_constraint(problems) -> None:
    prompt = saycan_prompt(problems["P2"], [])
    assert not prompt.asks_challenges
    backend = CannedRepliesBackendDouble(("plan = [('pick', 'salter')]",))
    vocabulary = Vocabulary.from_problem(problems["P2"])
    ask_for_task_plans(backend, vocabulary, prompt, 1, 0, constrained=True)
    constraint = backend.requests[0].constraint
    assert constraint is not None and CHALLENGES_HEADER not in constraint.gbnf


FIGURE12 = (Path(__file__).parents[1] / "llm" / "data" / "figure12_p6_reply.txt").read_text(
    encoding="utf-8"
)


@dataclass
class FinishReasonBackendDouble(CannedRepliesBackendDouble):
    """Test double: canned texts, each with the finish reason a server gives it."""

    finishes: tuple[str, ...] = ()

    def complete(self, request: LLMRequest) -> LLMResponse:
        self.requests.append(request)
        replies = tuple(
            LLMReply(self.texts[i], 10, 100, 0.01, self.finishes[i]) for i in range(request.n)
        )
        return LLMResponse(replies, self.name, self.model)


def test_a_reply_cut_by_max_tokens_keeps_its_complete_steps_and_is_marked(problems) -> None:
    # Figure 12's real reply cut inside its fifth step, as a 'length' finish cuts it
    cut = FIGURE12[: FIGURE12.index("('place', 'beef_grill'") + len("('place', 'beef_gr")]
    backend = FinishReasonBackendDouble((FIGURE12, cut), finishes=("stop", "length"))
    problem = problems["P6"]
    proposal = LLMProposer(backend).propose(
        ProposalRequest(problem, problem.initial_state, frozenset(), 2, seed=0)
    )
    whole = (
        Open("kitchen_door"),
        Pick("coke"),
        Place("coke", "on", "counter2"),
        Pick("beef_grill"),
        Place("beef_grill", "on", "counter2"),
        Pick("wine"),
        Place("wine", "on", "counter2"),
    )
    assert proposal.plans == (whole, whole[:4])
    assert proposal.truncated == (False, True) and proposal.truncated_plans == 1
    assert proposal.unparseable == ()


def test_feedback_reaches_the_prompt_only_when_given(problems) -> None:
    """--feedback: the failed steps go after the paper's prompt in Iterative-Replanning's
    words; without feedback the prompt is exactly the paper's."""
    from stalm.domain.outcome import Infeasibility, Outcome
    from stalm.proposers.feedback import failed_steps
    from stalm.search.concretize import ConcretePlan, ConcreteStep, TaskPlan

    problem = problems["P2"]
    state = problem.initial_state
    plan = (Open("kitchen_door"), Pick("bottle2"), Place("bottle2", "on", "table1"))
    why = Infeasibility("no_placement", "no free spot for 'bottle2' on 'table1'")
    step = ConcreteStep(state, plan[2], why, Outcome(state, -6.0, False, why))
    failed = ConcretePlan(
        0, TaskPlan(plan), (step,), False, "lack_of_3d_understanding", str(why), failed_step=2
    )
    feedback = failed_steps(problem, [failed])
    backend = CannedRepliesBackendDouble(("plan = [('pick', 'salter')]",))
    proposer = LLMProposer(backend)
    literals = [GroundLiteral("HandAvailable")]
    proposer.propose(ProposalRequest(problem, state, frozenset(literals), 1, seed=0))
    proposer.propose(
        ProposalRequest(problem, state, frozenset(literals), 1, seed=0, feedback=tuple(feedback))
    )
    plain, told = backend.requests
    assert "Failed plans" not in plain.user
    assert told.user.startswith(plain.user)
    assert "('place', 'bottle2', 'on', 'table1')" in told.user
    assert "at step 3" in told.user and "no free spot for 'bottle2' on 'table1'" in told.user
