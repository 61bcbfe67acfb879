"""WarmUpTree (Algorithm 4): put what Concretize explored into the search tree.

Each concretized plan becomes one path from the root: its continuous nodes and κ children are
added without the widening test (the κ was already paid for), an infeasible step becomes an
infeasible κ child (reward -6, terminal), and the states it reached become discrete nodes with
all their legal actions registered. Then the plan's value is backed up along the path exactly
as a simulation's is (this implementation's choice): incremental means, one visit per node,
root included. The authors' code instead overwrote node values with plain means and left the
root's count alone; keeping one update rule means warm-up statistics and search statistics mix
without bias.

The plan's leaf is worth its last reward r if the plan ended terminal (infeasible step, goal,
horizon) and r + γ·V(s') otherwise, with V the search's value function (a rollout).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stalm.domain.outcome import Infeasibility, Outcome
from stalm.domain.params import Action
from stalm.search.concretize import ConcretePlan
from stalm.search.policies import ValueFunction
from stalm.search.search_mdp import SearchMDP
from stalm.search.tree import Edge, SearchTree


@dataclass(frozen=True)
class WarmedPlan:
    """One plan as added: its path, the return backed up at each edge, and a goal plan if the
    plan (or the rollout from its leaf) reached the goal."""

    path: tuple[Edge, ...]
    returns: tuple[float, ...]
    goal_plan: tuple[Action, ...] | None
    first_outcome: Outcome | None


def add_plan(
    tree: SearchTree,
    mdp: SearchMDP,
    plan: ConcretePlan,
    rng: np.random.Generator,
    *,
    depth0: int,
    gamma: float,
    horizon: int,
    value: ValueFunction,
) -> WarmedPlan:
    """AddToTree for one concretized plan (which must start at the tree's root)."""
    if not plan.steps:
        return WarmedPlan((), (), None, None)
    if plan.steps[0].state != tree.root:
        raise ValueError(f"task plan {plan.index} was concretized from another state")
    path: list[Edge] = []
    actions: list[Action] = []
    depth = depth0
    tail = 0.0
    leaf = None
    goal_plan: tuple[Action, ...] | None = None
    last = len(plan.steps) - 1
    for position, step in enumerate(plan.steps):
        tree.add_action(step.state, step.action)
        tree.add_kappa(step.state, step.action, step.kappa, step.outcome)
        path.append(Edge(step.state, step.action, step.kappa))
        depth += 1
        outcome = step.outcome
        if isinstance(step.kappa, Infeasibility) or not outcome.feasible:
            break
        actions.append(step.kappa)
        if outcome.goal_reached:
            goal_plan = tuple(actions)
            break
        if depth >= horizon:
            break
        following = outcome.state
        if following not in tree:
            tree.add_node(following, mdp.legal_actions(following))
        if position == last:
            estimate = value(mdp, following, depth, rng, arrival=path[-1])
            tail = estimate.value
            leaf = following
            if estimate.goal_plan is not None:
                goal_plan = tuple(actions) + estimate.goal_plan
    returns = tree.backup(path, tail, gamma, leaf)
    return WarmedPlan(tuple(path), returns, goal_plan, plan.steps[0].outcome)


def warm_up_tree(
    tree: SearchTree,
    mdp: SearchMDP,
    plans: Sequence[ConcretePlan],
    rng: np.random.Generator,
    *,
    depth0: int,
    gamma: float,
    horizon: int,
    value: ValueFunction,
    deadline: float | None = None,
) -> tuple[WarmedPlan, ...]:
    """WarmUpTree: :func:`add_plan` for every plan, in order, stopping after a plan that
    reaches the goal (the search is then over), or before the next plan once the clock passes
    ``deadline`` (a ``time.monotonic()`` value)."""
    warmed: list[WarmedPlan] = []
    for plan in plans:
        if deadline is not None and time.monotonic() >= deadline:
            break
        done = add_plan(
            tree, mdp, plan, rng, depth0=depth0, gamma=gamma, horizon=horizon, value=value
        )
        warmed.append(done)
        if done.goal_plan is not None:
            break
    return tuple(warmed)
