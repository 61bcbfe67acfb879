"""The LLM proposer: prompt in, parsed task plans and unparseable replies out."""

from __future__ import annotations

from dataclasses import dataclass

from stalm.domain.actions import Pick, Place
from stalm.llm.backends.base import LLMReply, LLMRequest, LLMResponse
from stalm.planners.proposers import LLMProposer
from stalm.predicates.literals import GroundLiteral


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
    proposal = proposer.propose(problems["P2"], problems["P2"].initial_state, literals, 3, seed=9)
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
    proposal = proposer.propose(problems["P2"], problems["P2"].initial_state, [], 2, seed=0)
    assert proposal.plans == ((Pick("salter"),),)
    assert len(proposal.unparseable) == 1
    assert backend.requests[0].constraint is not None


def test_feedback_reaches_the_prompt_only_when_given(problems) -> None:
    """--feedback: the failed steps go after the paper's prompt in Iterative-Replanning's
    words; without feedback the prompt is exactly the paper's."""
    from stalm.domain.actions import Open
    from stalm.domain.outcome import Infeasibility, Outcome
    from stalm.planners.feedback import failed_steps
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
    proposer.propose(problem, state, literals, 1, seed=0)
    proposer.propose(problem, state, literals, 1, seed=0, feedback=feedback)
    plain, told = backend.requests
    assert "Failed plans" not in plain.user
    assert told.user.startswith(plain.user)
    assert "('place', 'bottle2', 'on', 'table1')" in told.user
    assert "at step 3" in told.user and "no free spot for 'bottle2' on 'table1'" in told.user
