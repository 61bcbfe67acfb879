"""Simulate (Algorithm 5) and WarmStartedUCT (Algorithm 3).

One simulation walks down from the root: a discrete action by the selection policy, a new κ
if progressive widening allows (a κ equal to an existing child is dropped), a κ child by the
selection policy, the stored outcome of T. It stops at an infeasible action, the goal, the
horizon (episode depth ``depth0`` + steps ≥ H), or a state without a node, which becomes a new
leaf valued r + γ·V(s'). The returns are then backed up along the path (``SearchTree.backup``).

WarmStartedUCT warms the tree with the concretized plans and runs up to N_budget simulations.
It stops the moment a plan reaches the goal, in warm-up, in the tree or in a leaf's rollout,
and returns that plan; otherwise it recommends one root action (``final_choice``). A wall-
clock deadline (a ``time.monotonic()`` value) is honoured between warm-up plans and between
simulations; a running simulation is never cut off, so the tree stays consistent.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from stalm.domain.outcome import Infeasibility, Outcome
from stalm.domain.params import Action
from stalm.search.concretize import ConcretePlan
from stalm.search.policies import SearchPolicies
from stalm.search.search_mdp import SearchMDP
from stalm.search.settings import SearchSettings
from stalm.search.transition import CountingMDP, apply, draw
from stalm.search.tree import Edge, SearchTree, TreeStats
from stalm.search.warmup import warm_up_tree
from stalm.world.state import State

SimulationEnd = Literal["goal", "infeasible", "horizon", "leaf", "dead_end"]
StopReason = Literal["goal", "budget", "deadline"]


@dataclass(frozen=True)
class Simulation:
    """One simulation: the edges taken, the return backed up at each, why it ended, and the
    plan to the goal if it found one (tree path plus, possibly, the leaf's rollout)."""

    path: tuple[Edge, ...]
    returns: tuple[float, ...]
    end: SimulationEnd
    goal_plan: tuple[Action, ...] | None


def simulate(
    tree: SearchTree,
    mdp: SearchMDP,
    rng: np.random.Generator,
    *,
    depth0: int,
    gamma: float,
    horizon: int,
    policies: SearchPolicies,
) -> Simulation:
    """Algorithm 5 from ``tree.root`` at episode depth ``depth0``; updates ``tree``."""
    state = tree.root
    depth = depth0
    path: list[Edge] = []
    actions: list[Action] = []
    tail = 0.0
    leaf: State | None = None
    goal_plan: tuple[Action, ...] | None = None
    end: SimulationEnd
    while True:
        stats = tree.action_stats(state)
        if not stats.keys:
            end, leaf = "dead_end", state
            break
        action = stats.keys[policies.select_action(stats, rng)]
        count = tree.num_kappas(state, action)
        if count == 0 or policies.widening(count, tree.action_visits(state, action)):
            kappa = draw(mdp, state, action, rng)
            if not tree.has_kappa(state, action, kappa):
                tree.add_kappa(state, action, kappa, apply(mdp, state, kappa))
        kappa_stats = tree.kappa_stats(state, action)
        kappa = kappa_stats.keys[policies.select_kappa(kappa_stats, rng)]
        edge = Edge(state, action, kappa)
        path.append(edge)
        depth += 1
        outcome = tree.outcome(edge)
        if isinstance(kappa, Infeasibility) or not outcome.feasible:
            end = "infeasible"
            break
        actions.append(kappa)
        if outcome.goal_reached:
            end, goal_plan = "goal", tuple(actions)
            break
        if depth >= horizon:
            end = "horizon"
            break
        following = outcome.state
        if following in tree:
            state = following
            continue
        tree.add_node(following, mdp.legal_actions(following))
        estimate = policies.value(mdp, following, depth, rng, arrival=edge)
        end, tail, leaf = "leaf", estimate.value, following
        if estimate.goal_plan is not None:
            goal_plan = tuple(actions) + estimate.goal_plan
        break
    returns = tree.backup(path, tail, gamma, leaf)
    return Simulation(tuple(path), returns, end, goal_plan)


@dataclass(frozen=True)
class SearchCounters:
    """The work one search did: warm-up plans added, simulations run, ψ draws and T calls
    (infeasible outcomes included; rollouts included)."""

    warm_start_plans: int
    simulations: int
    samples: int
    transitions: int


@dataclass(frozen=True)
class SearchResult:
    """What WarmStartedUCT found from one root.

    ``goal_plan`` is the actions from the root to the goal if any were found (then
    ``best_action`` is its first action). Otherwise ``best_action`` is the recommended root
    action (None if no root action has a feasible visited κ). ``best_outcome`` is T's outcome
    of ``best_action`` from the root as stored in the tree.
    """

    goal_plan: tuple[Action, ...] | None
    best_action: Action | None
    best_outcome: Outcome | None
    stop_reason: StopReason
    counters: SearchCounters
    tree_stats: TreeStats

    @property
    def success(self) -> bool:
        return self.goal_plan is not None


def warm_started_uct(
    mdp: SearchMDP,
    root: State,
    plans: Sequence[ConcretePlan],
    rng: np.random.Generator,
    *,
    settings: SearchSettings | None = None,
    depth0: int = 0,
    deadline: float | None = None,
    policies: SearchPolicies | None = None,
    tree: SearchTree | None = None,
) -> SearchResult:
    """Algorithm 3 from ``root`` at episode depth ``depth0``; with no plans, plain UCT.

    ``plans`` are Concretize's plans from ``root``. ``policies`` default to STaLM's (from
    ``settings``). Pass a ``tree`` rooted at ``root`` to keep it after the call (to inspect it
    or search on); otherwise a fresh one is used.
    """
    settings = settings or SearchSettings()
    policies = policies or SearchPolicies.from_settings(settings)
    if depth0 >= settings.horizon:
        raise ValueError(f"no steps left: depth0 = {depth0} >= horizon {settings.horizon}")
    counting = CountingMDP(mdp)
    if tree is None:
        tree = SearchTree.for_root(counting, root)
    elif tree.root != root:
        raise ValueError("the given tree is rooted at another state")
    warmed = 0
    simulations = 0

    def result(
        stop: StopReason, goal: tuple[Action, ...] | None = None, first: Outcome | None = None
    ) -> SearchResult:
        counters = SearchCounters(warmed, simulations, counting.samples, counting.transitions)
        return _result(tree, policies, stop, counters, goal, first)

    if mdp.is_goal(root):
        return result("goal", ())
    added = warm_up_tree(
        tree,
        counting,
        plans,
        rng,
        depth0=depth0,
        gamma=settings.gamma,
        horizon=settings.horizon,
        value=policies.value,
        deadline=deadline,
    )
    warmed = sum(1 for plan in added if plan.path)  # an empty task plan adds nothing
    if added and added[-1].goal_plan is not None:
        return result("goal", added[-1].goal_plan, added[-1].first_outcome)
    if len(added) < len(plans):  # the clock stopped the warm-up
        return result("deadline")
    for _ in range(settings.budget):
        if deadline is not None and time.monotonic() >= deadline:
            return result("deadline")
        simulation = simulate(
            tree,
            counting,
            rng,
            depth0=depth0,
            gamma=settings.gamma,
            horizon=settings.horizon,
            policies=policies,
        )
        simulations += 1
        if simulation.goal_plan is not None:
            return result("goal", simulation.goal_plan, tree.outcome(simulation.path[0]))
    return result("budget")


def _result(
    tree: SearchTree,
    policies: SearchPolicies,
    stop: StopReason,
    counters: SearchCounters,
    goal: tuple[Action, ...] | None,
    first: Outcome | None,
) -> SearchResult:
    """The result for a found goal plan (``first``: its first step's outcome), or else the
    final choice's recommendation at the root."""
    if goal is not None:
        best = goal[0] if goal else None
        return SearchResult(goal, best, first, stop, counters, tree.stats())
    choice = policies.final_choice(tree.node(tree.root))
    if choice is None:
        return SearchResult(None, None, None, stop, counters, tree.stats())
    kappa = choice[1].kappa
    action = None if isinstance(kappa, Infeasibility) else kappa
    return SearchResult(None, action, choice[1].outcome, stop, counters, tree.stats())
