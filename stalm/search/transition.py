"""Drawing κ and applying T, with the work counted, shared by Concretize, warm-up and UCT.

A continuous node's children are keyed by what ψ returned: a sampled :class:`Action`, or the
:class:`Infeasibility` saying why no κ was found. Keying infeasible draws by their reason makes
an infeasible draw an ordinary (terminal, -6) child, and a repeated identical failure a
duplicate that progressive widening drops instead of paying T again.

:class:`CountingMDP` wraps any :class:`SearchMDP` and counts the calls the search makes (ψ
draws and T calls, infeasible ones included). The counts live in the wrapper, which each search
creates for itself, so two searches over one domain never share a counter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stalm.domain.actions import DiscreteAction
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.domain.params import Action
from stalm.search.search_mdp import SearchMDP
from stalm.world.state import State

Kappa = Action | Infeasibility
"""A continuous node's child key: the sampled action α(δ, κ), or why ψ found none."""

PRECONDITION = "precondition"
"""The :attr:`Infeasibility.kind` of a discrete action whose symbolic precondition is false."""


@dataclass(frozen=True)
class WorkCounts:
    """How often the search called ψ (``samples``) and T (``transitions``, infeasible included)."""

    samples: int = 0
    transitions: int = 0


class CountingMDP:
    """A :class:`SearchMDP` that forwards every call to ``inner`` and counts ψ and T calls."""

    def __init__(self, inner: SearchMDP) -> None:
        self.inner = inner
        self.samples = 0
        self.transitions = 0

    def counts(self) -> WorkCounts:
        return WorkCounts(samples=self.samples, transitions=self.transitions)

    def legal_actions(self, state: State) -> tuple[DiscreteAction, ...]:
        return self.inner.legal_actions(state)

    def precondition_failure(self, state: State, action: DiscreteAction) -> str | None:
        return self.inner.precondition_failure(state, action)

    def sample(
        self, state: State, action: DiscreteAction, rng: np.random.Generator
    ) -> Action | Infeasibility:
        self.samples += 1
        return self.inner.sample(state, action, rng)

    def step(self, state: State, action: Action) -> Outcome:
        self.transitions += 1
        return self.inner.step(state, action)

    def infeasible(self, state: State, why: Infeasibility) -> Outcome:
        self.transitions += 1
        return self.inner.infeasible(state, why)

    def sample_and_step(
        self, state: State, action: DiscreteAction, rng: np.random.Generator
    ) -> tuple[Action | None, Outcome]:
        drawn = draw(self, state, action, rng, check_precondition=False)
        return (None if isinstance(drawn, Infeasibility) else drawn), apply(self, state, drawn)

    def is_goal(self, state: State) -> bool:
        return self.inner.is_goal(state)


def draw(
    mdp: SearchMDP,
    state: State,
    action: DiscreteAction,
    rng: np.random.Generator,
    *,
    check_precondition: bool = True,
) -> Kappa:
    """κ ~ ψ(s, α(δ)), or why there is none.

    With ``check_precondition`` a false symbolic precondition is reported without calling ψ:
    plans from a language model (and the tree nodes made from them) may hold illegal actions,
    and a sampler should not be asked to ground an action that cannot apply.
    """
    if check_precondition:
        why = mdp.precondition_failure(state, action)
        if why is not None:
            return Infeasibility(PRECONDITION, why)
    return mdp.sample(state, action, rng)


def apply(mdp: SearchMDP, state: State, kappa: Kappa) -> Outcome:
    """T(s, α(δ, κ)) for a drawn κ; an infeasible draw gives the absorbing failure outcome."""
    if isinstance(kappa, Infeasibility):
        return mdp.infeasible(state, kappa)
    return mdp.step(state, kappa)
