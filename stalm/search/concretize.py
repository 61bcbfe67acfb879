"""Concretize (Algorithm 2): ground task plans with sampled κ and classify the failures.

For each task plan, step by step from the start state: draw κ ~ ψ(s, α(δ)), apply T, and stop
the plan at its first infeasible step or at the horizon; stop everything at the first state
that satisfies the goal. Every step is recorded (state, discrete action, κ key, outcome), so
WarmUpTree can add exactly what was explored to the search tree without paying T again.

Failed plans are classified as in the paper's Figure 5 (§4.4), plus two kinds for a plan the
caller does not have:

* ``precondition_violation`` — a step's symbolic precondition is false in the state it is
  tried in (the model ignored the state or its own earlier steps);
* ``lack_of_3d_understanding`` — the precondition holds but ψ found no feasible κ (geometry
  the prompt cannot convey: occlusion, size, reachability);
* ``partially_achieved_goal`` — every step tried was feasible but the goal does not hold
  (also when the horizon cut the plan; see :attr:`ConcretePlan.truncated`);
* ``unparseable`` — a model's reply that could not be read (the caller passes an empty plan
  with the parser's reason);
* ``no_plan`` — a planning proposer (the symbolic one) found no plan: not a misread reply but
  a search that came back empty (an empty plan with the planner's reason).

These are the transition's kinds. Figure 5 counts a plan whose first step the prompt's own
predicates call occluded as a precondition violation too; planners count failures through
:func:`stalm.search.failure_kinds.figure5_kinds`, which applies that rule.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from stalm.domain.actions import DiscreteAction, Place
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.domain.params import Action
from stalm.search.search_mdp import SearchMDP
from stalm.search.transition import PRECONDITION, CountingMDP, Kappa, WorkCounts, apply, draw
from stalm.world.state import State

Figure5Kind = Literal[
    "precondition_violation", "lack_of_3d_understanding", "partially_achieved_goal"
]
"""Figure 5's three kinds of task-plan error (the noisy proposer injects the same three)."""
FIGURE5_KINDS: tuple[Figure5Kind, ...] = get_args(Figure5Kind)
FailureKind = Literal[Figure5Kind, "unparseable", "no_plan"]
FAILURE_KINDS: tuple[FailureKind, ...] = (*FIGURE5_KINDS, "unparseable", "no_plan")


@dataclass(frozen=True)
class TaskPlan:
    """A task plan: discrete actions in order, or why the caller has none.

    A reply the parser could not read still counts as one of the batch's plans (Figure 5
    reports how many of them there were), so it is passed as an empty plan with its reason
    (``unparseable``). So is a planning proposer's search that found no plan (``no_plan``),
    which is no misread reply and is counted apart.
    """

    actions: tuple[DiscreteAction, ...]
    unparseable: str | None = None
    no_plan: str | None = None

    def __post_init__(self) -> None:
        if self.unparseable is not None and self.actions:
            raise ValueError("a TaskPlan marked unparseable must have no actions")
        if self.no_plan is not None and (self.actions or self.unparseable is not None):
            raise ValueError("a TaskPlan marked no_plan must have no actions and be no reply")

    @staticmethod
    def unreadable(reason: str) -> TaskPlan:
        """A model's reply the parser could not read, as a plan (kind ``unparseable``)."""
        return TaskPlan((), reason)

    @staticmethod
    def none_found(reason: str) -> TaskPlan:
        """A planning proposer's search that found no plan, as a plan (kind ``no_plan``)."""
        return TaskPlan((), no_plan=reason)


@dataclass(frozen=True)
class ConcreteStep:
    """One grounded step: the state it was tried in, α(δ), the κ key and T's outcome.

    ``kappa`` is the sampled :class:`Action`, or the :class:`Infeasibility` when ψ found no κ
    (or the precondition was false); it is the key the step gets in the search tree.
    """

    state: State
    action: DiscreteAction
    kappa: Kappa
    outcome: Outcome

    @property
    def params(self) -> Action | None:
        """The sampled action α(δ, κ), or None for an infeasible step."""
        return None if isinstance(self.kappa, Infeasibility) else self.kappa

    @property
    def infeasibility(self) -> Infeasibility | None:
        """Why the step is infeasible: ψ found no κ, or T's outcome says; None if feasible."""
        return self.kappa if isinstance(self.kappa, Infeasibility) else self.outcome.failure


@dataclass(frozen=True)
class ConcretePlan:
    """What Concretize did with one task plan.

    ``failure`` is None exactly when ``reached_goal``. ``failed_step`` is the index of the
    infeasible step, if any; ``truncated`` says the horizon stopped the plan before its last
    step; ``detail`` is one sentence on what went wrong.
    """

    index: int
    task_plan: TaskPlan
    steps: tuple[ConcreteStep, ...]
    reached_goal: bool
    failure: FailureKind | None
    detail: str | None = None
    failed_step: int | None = None
    truncated: bool = False

    @property
    def actions(self) -> tuple[Action, ...]:
        """The feasible prefix as concrete actions α(δ, κ)."""
        return tuple(step.params for step in self.steps if step.params is not None)


@dataclass(frozen=True)
class ConcretizeResult:
    """Algorithm 2's (success, Plans), with the goal-reaching plan and the work done.

    ``plans`` holds the task plans tried, in order; after a success the remaining plans are
    not tried and do not appear. ``solution`` is the successful plan's actions.
    """

    success: bool
    plans: tuple[ConcretePlan, ...]
    solution: tuple[Action, ...] | None
    counts: WorkCounts

    @property
    def failures(self) -> tuple[tuple[int, FailureKind], ...]:
        """(task-plan index, failure kind) for every failed plan."""
        return tuple((p.index, p.failure) for p in self.plans if p.failure is not None)


def concretize(
    mdp: SearchMDP,
    state: State,
    task_plans: Sequence[TaskPlan],
    rng: np.random.Generator,
    *,
    depth0: int = 0,
    horizon: int = 20,
    kappa_tries: int = 1,
    backtracks: int = 0,
) -> ConcretizeResult:
    """Ground ``task_plans`` from ``state`` (episode depth ``depth0``, horizon H = ``horizon``).

    ``kappa_tries`` κ draws per step before the step counts as infeasible: 1 in Algorithm 2
    (ψ itself makes the operator's number of tries), 3 in the authors' code. A symbolic
    precondition failure is final on the first draw. Every draw is paid for by ψ; only the
    last one becomes the step (and the tree's κ child). ``backtracks`` (beyond the paper, 0
    in Algorithm 2): when a step fails because an object this plan put down is in the way,
    that placement is drawn again and the plan goes on from there, at most this many times
    per plan; only the last attempt's steps are kept.
    """
    if kappa_tries < 1:
        raise ValueError(f"kappa_tries must be at least 1, got {kappa_tries}")
    counting = CountingMDP(mdp)
    plans: list[ConcretePlan] = []
    for index, task_plan in enumerate(task_plans):
        plan = _concretize_one(
            counting, state, index, task_plan, rng, depth0, horizon, kappa_tries, backtracks
        )
        plans.append(plan)
        if plan.reached_goal:
            return ConcretizeResult(True, tuple(plans), plan.actions, counting.counts())
    return ConcretizeResult(False, tuple(plans), None, counting.counts())


def _concretize_one(
    mdp: SearchMDP,
    start: State,
    index: int,
    task_plan: TaskPlan,
    rng: np.random.Generator,
    depth0: int,
    horizon: int,
    kappa_tries: int = 1,
    backtracks: int = 0,
) -> ConcretePlan:
    if not task_plan.actions:
        if task_plan.no_plan is not None:
            return ConcretePlan(index, task_plan, (), False, "no_plan", task_plan.no_plan)
        reason = task_plan.unparseable or "the task plan is empty"
        return ConcretePlan(index, task_plan, (), False, "unparseable", reason)
    actions = task_plan.actions
    steps: list[ConcreteStep] = []
    state = start
    position = 0
    done = 0  # backtracks so far
    while position < len(actions):
        action = actions[position]
        if depth0 + position >= horizon:
            detail = f"the horizon H = {horizon} stopped the plan after {position} step(s)"
            failure: FailureKind = "partially_achieved_goal"
            return ConcretePlan(
                index, task_plan, tuple(steps), False, failure, detail, truncated=True
            )
        kappa = draw(mdp, state, action, rng)
        for _ in range(kappa_tries - 1):
            if not isinstance(kappa, Infeasibility) or kappa.kind == PRECONDITION:
                break
            kappa = draw(mdp, state, action, rng)
        outcome = apply(mdp, state, kappa)
        steps.append(ConcreteStep(state, action, kappa, outcome))
        if isinstance(kappa, Infeasibility) or not outcome.feasible:
            why = steps[-1].infeasibility
            redo = _placement_to_redo(steps, why, done) if done < backtracks else None
            if redo is not None:
                # an object this plan put down is in the way: draw that placement again
                done += 1
                state = steps[redo].state
                del steps[redo:]
                position = redo
                continue
            kind: FailureKind = (
                "precondition_violation"
                if why is not None and why.kind == PRECONDITION
                else "lack_of_3d_understanding"
            )
            detail = f"step {position} {action} is infeasible: {why}"
            return ConcretePlan(
                index, task_plan, tuple(steps), False, kind, detail, failed_step=position
            )
        if outcome.goal_reached:
            return ConcretePlan(index, task_plan, tuple(steps), True, None)
        state = outcome.state
        position += 1
    detail = f"all {len(steps)} step(s) are feasible but the goal does not hold"
    return ConcretePlan(index, task_plan, tuple(steps), False, "partially_achieved_goal", detail)


def _placement_to_redo(
    steps: Sequence[ConcreteStep], why: Infeasibility | None, done: int
) -> int | None:
    """An earlier step of this plan that put down an object the failure names as in the way
    (P5: the cans drawn at the front of the counter the grill must go on), or None. The
    ``done``-th backtrack takes the candidates in turn, latest first, so every named object's
    placement gets drawn again, not just the last one's."""
    if why is None or why.kind == PRECONDITION or not why.blockers:
        return None
    candidates = [
        position
        for position in range(len(steps) - 2, -1, -1)
        if isinstance(steps[position].action, Place)
        and getattr(steps[position].action, "obj", None) in why.blockers
    ]
    return candidates[done % len(candidates)] if candidates else None
