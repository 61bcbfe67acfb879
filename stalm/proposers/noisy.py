"""The noisy proposer: another proposer's task plans, corrupted on purpose (``--proposer noisy``).

It is a *degraded* proposer for measuring what the warm-started tree is worth, never a
language model and never to be reported as one: it wraps a proposer (the symbolic one by
default, ``proposer.noise.inner``) and corrupts each plan of its batch with probability
``proposer.noise.rate`` with one of Figure 5's kinds of error (:mod:`stalm.proposers.plan_noise`),
drawn by ``proposer.noise.weights``. The draws come from a generator seeded by the query's
seed alone (:func:`noise_rng`), so the same trial seed gives the same corruptions, and nothing
else of the trial draws from it.

Its proposals say, per plan, what was injected (:attr:`Proposal.injected`); STaLM records that
beside the Figure 5 kind Concretize's outcome is classified as (:func:`injected_records`,
``details["noise"]`` of a result), which ``stalm report`` tabulates against each other. The
two need not agree: the classifier calls a plan a precondition violation only when its
*first* step is occluded, while a dropped clearing step often leaves a later one occluded.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from stalm.errors import StalmError
from stalm.json_object import JsonObject, record_json
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.plan_noise import PlanContext, corrupt_plans
from stalm.proposers.protocol import Proposal, ProposalRequest, TaskPlanProposer
from stalm.search.concretize import ConcretePlan
from stalm.search.failure_kinds import figure5_kind
from stalm.settings.tree import NOISE_KINDS

NOISE_STREAM = 0x6E6F697379
"""Mixed into the query's seed (``b"noisy"``) so the noise draws are a stream of their own."""


def noise_rng(seed: int) -> np.random.Generator:
    """The generator of one query's corruptions, from the query's seed alone."""
    return np.random.default_rng([seed % 2**64, NOISE_STREAM])


@dataclass(frozen=True)
class NoisyProposer:
    """A proposer whose plans are ``inner``'s, each corrupted with probability ``rate``."""

    inner: TaskPlanProposer
    rate: float = 0.5
    weights: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        if not 0.0 <= self.rate <= 1.0:
            raise StalmError(f"the noisy proposer's rate must be in [0, 1], got {self.rate}")
        if len(self.weights) != len(NOISE_KINDS) or min(self.weights) < 0 or not any(self.weights):
            raise StalmError(
                f"the noisy proposer's weights must be {len(NOISE_KINDS)} numbers >= 0, not all "
                f"0, got {self.weights}"
            )

    @property
    def name(self) -> str:
        return f"noisy:{self.rate:g}:{self.inner.name}"

    def record(self, plans: Sequence[InjectedPlan]) -> NoiseRecord:
        """What a result records of this proposer (``details["noise"]``): its settings and
        ``plans``, what it injected into each plan and how that plan's outcome was
        classified."""
        return NoiseRecord(self.rate, self.weights, self.inner.name, tuple(plans))

    @property
    def takes_feedback(self) -> bool:
        """Feedback (``--feedback``; off by default for this proposer) goes to ``inner``."""
        return self.inner.takes_feedback

    def propose(self, request: ProposalRequest) -> Proposal:
        """``inner``'s proposal with its plans corrupted."""
        if request.feedback and not self.inner.takes_feedback:
            raise StalmError(
                f"the proposer {self.inner.name} takes no feedback: switch feedback off"
            )
        proposal = self.inner.propose(request)
        plans, injected = corrupt_plans(
            proposal.plans,
            PlanContext.of(request.problem, request.literals),
            self.rate,
            self.weights,
            noise_rng(request.seed),
        )
        return replace(proposal, plans=plans, injected=injected)


@dataclass(frozen=True)
class InjectedPlan:
    """One plan of a noisy proposal: what was injected into it and the Figure 5 kind its
    outcome is classified as."""

    step: int
    round: int
    index: int
    injected: str
    kind: str


@dataclass(frozen=True)
class NoiseRecord:
    """The noisy proposer's settings and its plans (:class:`InjectedPlan`), for a result."""

    rate: float
    weights: tuple[float, float, float]
    inner: str
    plans: tuple[InjectedPlan, ...]

    def to_json(self) -> JsonObject:
        """The fields as JSON, the weights by kind."""
        return record_json(self) | {"weights": dict(zip(NOISE_KINDS, self.weights, strict=True))}


def injected_records(
    step: int,
    round_: int,
    injected: Sequence[str],
    concretized: Sequence[ConcretePlan],
    root_literals: Iterable[GroundLiteral],
) -> list[InjectedPlan]:
    """Per plan of one noisy proposal: what was injected and the Figure 5 kind its outcome is
    classified as (``reached_goal`` if it reached the goal, ``not_tried`` if Concretize
    stopped at an earlier goal plan before trying it)."""
    literals = frozenset(root_literals)
    by_index = {plan.index: plan for plan in concretized}
    records = []
    for index, label in enumerate(injected):
        plan = by_index.get(index)
        classified = "not_tried" if plan is None else figure5_kind(plan, literals)
        records.append(InjectedPlan(step, round_, index, label, classified or "reached_goal"))
    return records
