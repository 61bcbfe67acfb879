"""Test doubles for proposers (tests only): known task plans instead of a language model."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from stalm.domain.actions import DiscreteAction
from stalm.domain.mdp import Domain
from stalm.proposers.protocol import Proposal, ProposalRequest
from stalm.settings.io import with_values
from stalm.settings.tree import RunSettings
from stalm.world.problem import Problem


def plain_settings(sims: int, *overrides: tuple[str, Any]) -> RunSettings:
    """A settings tree with N_budget ``sims`` and the plain step the tree planners' tests were
    written for -- the authors' best-Q rule, Algorithm 2's one κ draw, no backtracks, no
    geometric feedback whatever the proposer -- then ``overrides`` (dotted key, value)."""
    plain = [
        ("search.sims", sims),
        ("execution.rule", "best_q"),
        ("execution.kappa_tries", 1),
        ("execution.feedback", False),
        ("execution.backtracks", 0),
    ]
    return with_values(RunSettings(), [*plain, *overrides], "test settings")


class ScriptedSuffixProposer:
    """Proposes suffixes of one known task plan, like a model re-planning from the current
    state: the longest suffixes whose first step's symbolic precondition holds now."""

    name = "scripted-test-double"
    takes_feedback = False

    def __init__(self, problem: Problem, plan: Sequence[DiscreteAction]) -> None:
        self.plan = tuple(plan)
        self._domain_for_checks = Domain.create(problem)
        self.calls = 0

    def propose(self, request: ProposalRequest) -> Proposal:
        self.calls += 1
        suffixes = [
            self.plan[i:]
            for i in range(len(self.plan))
            if self._domain_for_checks.precondition_failure(request.state, self.plan[i]) is None
        ]
        return Proposal(plans=tuple(suffixes[: request.n]), calls=1)

    def close(self) -> None:
        self._domain_for_checks.close()
