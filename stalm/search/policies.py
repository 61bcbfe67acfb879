"""The choices WarmStartedUCT makes, as small swappable policies (mctx-style).

* selection — which child to follow (UCT here; a PUCT with language-model priors later);
* widening — whether a continuous node draws a new κ (progressive widening);
* value — what a new leaf is worth (a random rollout here; Hcount later);
* final choice — which root action to recommend when no plan reached the goal.

Each policy is a frozen dataclass or plain function; all randomness comes from the
``numpy.random.Generator`` passed in, so the same seed gives the same search.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from stalm.domain.outcome import Infeasibility
from stalm.domain.params import Action
from stalm.search.search_mdp import SearchMDP
from stalm.search.settings import SearchSettings
from stalm.search.transition import apply, draw
from stalm.search.tree import ChildStats, ContinuousNodeView, DiscreteNodeView, Edge, KappaView
from stalm.world.state import State

# ------------------------------------------------------------------------------ selection


class SelectionPolicy(Protocol):
    """Pick the index of one child in ``stats`` (which has at least one child)."""

    def __call__(self, stats: ChildStats, rng: np.random.Generator) -> int: ...


def argmax_random_tie(scores: np.ndarray, rng: np.random.Generator) -> int:
    """Index of the highest score; exact ties are broken uniformly with ``rng``.

    ``rng`` is drawn from only when there is a tie, so the random stream (and with it the rest
    of a seeded search) moves only when a choice is really random.
    """
    best = np.flatnonzero(scores == scores.max())
    if best.size == 1:
        return int(best[0])
    return int(best[rng.integers(best.size)])


@dataclass(frozen=True)
class UCTSelection:
    """UCT as the authors ran it: Q + c·sqrt(ln(N_parent + 1) / (N_child + 1)).

    Q is the raw mean return (not normalised, hence c = 50 for rewards of -6..+100). The +1 in
    both counts keeps the score finite: an unvisited child gets a large but finite bonus, not
    the textbook infinity, so a child with a high Q can be preferred to an untried one.
    """

    c: float

    def scores(self, stats: ChildStats) -> np.ndarray:
        q = np.asarray(stats.q, dtype=float)
        n = np.asarray(stats.n, dtype=float)
        return q + self.c * np.sqrt(math.log(stats.parent_visits + 1) / (n + 1.0))

    def __call__(self, stats: ChildStats, rng: np.random.Generator) -> int:
        return argmax_random_tie(self.scores(stats), rng)


# ------------------------------------------------------------------------------ widening


class WideningPolicy(Protocol):
    """Whether a continuous node with ``num_children`` κ children and ``visits`` earlier visits
    draws a new κ on this visit."""

    def __call__(self, num_children: int, visits: int) -> bool: ...


@dataclass(frozen=True)
class ProgressiveWidening:
    """Draw a new κ while #children ≤ k·N^α, N the node's visits before this one.

    Counting N before the current visit gives, for k = 1.5 and α = 0.15, one child at
    N = 0, two at N = 1, three from N = 7, four from N = 102.
    """

    k: float
    alpha: float

    def __call__(self, num_children: int, visits: int) -> bool:
        return num_children <= self.k * float(visits) ** self.alpha


# ------------------------------------------------------------------------------ leaf values


@dataclass(frozen=True)
class LeafValue:
    """A leaf estimate, and the actions to the goal if the estimate found a way there.

    A rollout that reaches the goal has found a plan; ``goal_plan`` hands its actions back
    so the search can stop and return them instead of averaging them away.
    """

    value: float
    goal_plan: tuple[Action, ...] | None = None


class ValueFunction(Protocol):
    """V(s) for a new leaf at episode depth ``depth`` (steps since the episode start).

    The MDP and the generator are passed in rather than stored, so a value function can be
    plain settings (frozen, shareable) and its ψ and T calls go through the search's counting
    wrapper. ``arrival`` is the edge the search took into the leaf (None when there is none),
    so an estimate that is costly from scratch can be derived from the parent's instead (Hcount
    brings the parent's predicates forward). A deterministic estimate ``(state, depth) ->
    float`` plugs in through :class:`StateValue`.
    """

    def __call__(
        self,
        mdp: SearchMDP,
        state: State,
        depth: int,
        rng: np.random.Generator,
        arrival: Edge | None = None,
    ) -> LeafValue: ...


RolloutEnd = Literal["goal", "infeasible", "horizon", "dead_end"]


@dataclass(frozen=True)
class Rollout:
    """One random rollout: its discounted return, the feasible actions taken, why it ended."""

    value: float
    actions: tuple[Action, ...]
    steps: int
    end: RolloutEnd


def rollout(
    mdp: SearchMDP,
    state: State,
    depth: int,
    rng: np.random.Generator,
    *,
    gamma: float,
    horizon: int,
) -> Rollout:
    """Uniformly random legal discrete actions with κ from ψ, until the horizon, the goal or
    an infeasible action; return Σ_t γ^t·r_t (the first reward undiscounted, discounted once).

    A state without legal actions ends the rollout (a dead end, possible only in test MDPs).
    """
    total = 0.0
    discount = 1.0
    actions: list[Action] = []
    steps = 0
    end: RolloutEnd = "horizon"
    while depth + steps < horizon:
        legal = mdp.legal_actions(state)
        if not legal:
            end = "dead_end"
            break
        discrete = legal[int(rng.integers(len(legal)))]
        kappa = draw(mdp, state, discrete, rng, check_precondition=False)
        outcome = apply(mdp, state, kappa)
        total += discount * outcome.reward
        discount *= gamma
        steps += 1
        if isinstance(kappa, Infeasibility) or not outcome.feasible:
            end = "infeasible"
            break
        actions.append(kappa)
        if outcome.goal_reached:
            end = "goal"
            break
        state = outcome.state
    return Rollout(value=total, actions=tuple(actions), steps=steps, end=end)


@dataclass(frozen=True)
class RolloutValue:
    """The default leaf value: the return of one random rollout (§3.3, Algorithm 5 L20)."""

    gamma: float
    horizon: int

    def __call__(
        self,
        mdp: SearchMDP,
        state: State,
        depth: int,
        rng: np.random.Generator,
        arrival: Edge | None = None,
    ) -> LeafValue:
        result = rollout(mdp, state, depth, rng, gamma=self.gamma, horizon=self.horizon)
        return LeafValue(result.value, result.actions if result.end == "goal" else None)


@dataclass(frozen=True)
class StateValue:
    """Adapts a deterministic estimate ``fn(state, depth)`` (e.g. Hcount) to a ValueFunction."""

    fn: Callable[[State, int], float]

    def __call__(
        self,
        mdp: SearchMDP,
        state: State,
        depth: int,
        rng: np.random.Generator,
        arrival: Edge | None = None,
    ) -> LeafValue:
        return LeafValue(self.fn(state, depth))


# ------------------------------------------------------------------------------ final choice


class FinalChoice(Protocol):
    """The root action to recommend when the search found no plan to the goal."""

    def __call__(self, root: DiscreteNodeView) -> tuple[ContinuousNodeView, KappaView] | None: ...


def best_by_q(root: DiscreteNodeView) -> tuple[ContinuousNodeView, KappaView] | None:
    """The highest-Q discrete child, then its highest-Q κ child; ties go to more visits,
    then to the earlier child (this implementation's tie rule; the paper gives none).

    Only visited, feasible κ children count (and discrete children that have one): a κ known
    to be infeasible would leave the real state unchanged, so it is never recommended. None if
    no root action has a feasible visited κ.
    """
    best: tuple[ContinuousNodeView, KappaView] | None = None
    for cont in root.children:
        kappas = [k for k in cont.children if k.n > 0 and k.outcome.feasible]
        if not kappas:
            continue
        if best is None or (cont.q, cont.n) > (best[0].q, best[0].n):
            kappa = kappas[0]
            for candidate in kappas[1:]:
                if (candidate.q, candidate.n) > (kappa.q, kappa.n):
                    kappa = candidate
            best = (cont, kappa)
    return best


# ------------------------------------------------------------------------------ bundle


@dataclass(frozen=True)
class SearchPolicies:
    """Every policy one search uses; baselines replace single fields."""

    select_action: SelectionPolicy
    select_kappa: SelectionPolicy
    widening: WideningPolicy
    value: ValueFunction
    final_choice: FinalChoice

    @staticmethod
    def from_settings(settings: SearchSettings) -> SearchPolicies:
        """STaLM's policies: UCT at both node kinds, progressive widening, random rollouts."""
        uct = UCTSelection(settings.c)
        return SearchPolicies(
            select_action=uct,
            select_kappa=uct,
            widening=ProgressiveWidening(settings.k, settings.alpha),
            value=RolloutValue(settings.gamma, settings.horizon),
            final_choice=best_by_q,
        )
