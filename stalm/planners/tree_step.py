"""The end of every tree planner's real step (STaLM, STaLM w/o UCT, UCT, UCT-with-Hcount).

Without a plan that reached the goal they run (warm-started) UCT from the current state and
execute what the execution rule chooses (:func:`search`; STaLM w/o UCT takes the best plan's
first action instead). UCT's step is only that (:class:`SearchStep`); STaLM's first gets task
plans and Concretizes them (:class:`stalm.planners.stalm.StalmStep`). Each step fills a
:class:`~stalm.trial.step_log.StepRecord` and reads the run's settings tree (``search.sims``
filled by the planner's registry row), with its two additions to the paper: tree reuse
(:meth:`stalm.trial.online.Trial.execute`) and the 'progress' execution rule, which searches
on from the same root rather than spend an irreversible step of the horizon on a coin toss
(:func:`_best_promising_action`; the authors' 'best_q' does).

What a tree planner records of its run is :class:`TreeDetails`: which proposer it asked and how
often, the settings that decide how it searched and executed, the root visits a kept tree
brought into each step, and the step log; the noisy proposer adds what it injected, Hcount how
its leaves' predicates were made.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import cast

from stalm.domain.mdp import Domain
from stalm.domain.params import Action
from stalm.json_object import JsonObject, record_json
from stalm.progress import Progress
from stalm.proposers.noisy import NoiseRecord
from stalm.search import (
    ConcretePlan,
    SearchPolicies,
    SearchResult,
    SearchSettings,
    SearchTree,
    warm_started_uct,
)
from stalm.search.hcount import HcountLeafValue
from stalm.settings.tree import ExecutionRule, RunSettings
from stalm.trial.online import Decision, OnlinePlanner, StartSteps, Trial
from stalm.trial.step_log import DECISIONS, StepRecord, tree_record, warm_edges
from stalm.world.state import State

log = logging.getLogger(__name__)
"""Each real step's search and the rule that chose what it executes, at INFO."""


@dataclass(frozen=True)
class TreeSettingsRecord:
    """The settings a tree planner's record keeps (``details.settings``): each is explained
    where the run's settings tree declares it."""

    reuse_tree: bool
    feedback: bool
    execution: ExecutionRule
    kappa_tries: int
    backtracks: int
    goal_atom_lost: float


@dataclass(frozen=True)
class HcountLeaves:
    """How Hcount's leaves got their predicates: computed from scratch, or brought forward
    from the parent's with the cached update."""

    predicates_from_scratch: int
    predicates_brought_forward: int


@dataclass(frozen=True)
class TreeDetails:
    """A tree planner's record (``proposer`` None and ``proposals`` 0 for UCT)."""

    proposer: str | None
    settings: TreeSettingsRecord
    proposals: int
    feedback_steps_learned: int
    reused_root_visits: tuple[int, ...]
    """Per real step whose tree was kept: the visits its root already had."""
    step_log: tuple[StepRecord, ...]
    noise: NoiseRecord | None = None
    hcount_leaves: HcountLeaves | None = None

    def to_json(self) -> JsonObject:
        return record_json(self, omitted_when_none={"noise", "hcount_leaves"})


def tree_planner(
    name: str,
    settings: RunSettings,
    start: StartSteps,
    progress: Progress | None,
    *,
    leaf_occlusion: bool = False,
) -> OnlinePlanner:
    """The online loop around a tree planner's steps. The trial computes PickOccludedBy and
    PlaceOccludedBy for the prompt (not for Table 4's arms whose prompt does not show them,
    so those arms do not pay for motion planning they never use), for the symbolic proposer
    (which plans with occlusions whatever the prompt options say), for the noisy one (which
    needs them to drop the step that clears an occluder) and for a leaf value that reads
    them (``leaf_occlusion``: Hcount)."""
    occlusion = settings.proposer.kind != "llm" or settings.prompt.occlusion_predicates
    return OnlinePlanner(name, settings, start, progress, occlusion=leaf_occlusion or occlusion)


@dataclass
class SearchStep:
    """UCT's real step: search from the current state, execute what the execution rule
    chooses (:func:`search`, the end of every tree planner's step)."""

    trial: Trial
    settings: RunSettings
    policies: SearchPolicies
    hcount: HcountLeafValue | None = None
    """Hcount's leaf value, whose count of how its predicates came the details record."""
    step_log: list[StepRecord] = field(default_factory=list)

    def decide(self) -> Decision:
        record = begin_step(self.trial, self.step_log)
        if self.trial.episode.out_of_time():
            return record.timed_out()
        # nothing feasible found (an empty plan): the loop asks again from the same state
        return record.executes(search(self.trial, self.settings, self.policies, [], record))

    def details(self) -> TreeDetails:
        details = tree_details(self.trial, self.settings, self.step_log, feedback=False)
        if self.hcount is None:
            return details
        leaves = HcountLeaves(self.hcount.computed_from_scratch, self.hcount.brought_forward)
        return replace(details, hcount_leaves=leaves)


def begin_step(trial: Trial, step_log: list[StepRecord]) -> StepRecord:
    """A new real step, counted; its record (:mod:`stalm.trial.step_log`) is added to
    ``step_log`` and filled in by the parts of the step it is handed to."""
    trial.replans += 1
    record = StepRecord(trial.done)
    step_log.append(record)
    return record


def tree_details(
    trial: Trial, settings: RunSettings, step_log: list[StepRecord], *, feedback: bool
) -> TreeDetails:
    """A tree planner's record for ``PlanResult.details`` (no proposer: STaLM's adds its own;
    ``feedback`` is off for a planner that proposes no task plans)."""
    return TreeDetails(
        proposer=None,
        settings=TreeSettingsRecord(
            reuse_tree=trial.reuse_tree,
            feedback=feedback,
            execution=settings.execution.rule,
            kappa_tries=settings.execution.kappa_tries,
            backtracks=settings.backtracks(),
            goal_atom_lost=trial.domain.reward_settings.goal_atom_lost,
        ),
        proposals=0,
        feedback_steps_learned=0,
        reused_root_visits=tuple(trial.reused_root_visits),
        step_log=tuple(step_log),
    )


def search(
    trial: Trial,
    settings: RunSettings,
    policies: SearchPolicies,
    plans: list[ConcretePlan],
    record: StepRecord,
) -> tuple[Action, ...]:
    """WarmStartedUCT (Algorithms 3-5) from the current state, warm-started with ``plans``:
    the tree's goal plan if a simulation finds one, else one root action chosen by the
    execution rule; ``record`` is told which, and how the tree looks after the search."""
    domain, state, done = trial.domain, trial.episode.state, trial.done
    rule, rounds = settings.execution.rule, settings.execution.search_rounds
    within = trial.within_horizon(settings.search.search_settings())
    tree = trial.tree_at(state)
    visits_before = tree.visits(state)
    step_end = trial.share_end(settings.execution.step_share)
    searches = 0

    def decided(how: str) -> None:
        record.decision = how
        record.searches = searches
        record.tree = tree_record(tree, warm_edges(plans), visits_before)
        log.info("step %d: %d search(es): %s", done, searches, DECISIONS.get(how, how))

    warm = plans
    while True:
        searches += 1
        trial.say(f"step {done}: warm-started UCT, {within.budget} simulations")
        result = tree_search(trial, warm, within, policies, tree)
        if result.goal_plan:
            decided("tree_goal")
            return result.goal_plan
        if result.best_action is None:
            decided("nothing")
            return ()
        if rule == "best_q":
            decided("best_q")
            return (result.best_action,)
        promising = _best_promising_action(tree, domain)
        if promising is not None:
            decided("progress")
            return (promising,)
        if (
            result.stop_reason == "deadline"
            or searches >= rounds
            or time.monotonic() >= step_end
            or within.budget == 0
        ):
            decided("best_q_fallback")
            return (result.best_action,)
        warm = []


def tree_search(
    trial: Trial,
    plans: Sequence[ConcretePlan],
    settings: SearchSettings,
    policies: SearchPolicies,
    tree: SearchTree | None,
) -> SearchResult:
    """WarmStartedUCT from the current state (every online tree method's search, LLM-MCTS's
    too), timed as the trial's 'tree' phase, its simulations counted."""
    with trial.phase("tree"):
        result = warm_started_uct(
            trial.domain,
            trial.episode.state,
            plans,
            trial.rng,
            settings=settings,
            depth0=trial.done,
            deadline=trial.episode.deadline,
            policies=policies,
            tree=tree,
        )
    trial.simulations += result.counters.simulations
    return result


def _best_promising_action(tree: SearchTree, domain: Domain) -> Action | None:
    """The 'progress' rule: the highest-Q root action whose subtree holds a state with more
    goal conjuncts true than the root (the tree knows a way on from it to goal progress),
    with the highest-Q of its feasible κ that lead there; None if no root action leads to
    progress."""
    root = tree.node(tree.root)
    baseline = domain.goal_atoms_true(tree.root)
    best: tuple[float, int, Action] | None = None
    for cont in root.children:
        if best is not None and (cont.q, cont.n) <= best[:2]:
            continue
        kappas = [k for k in cont.children if k.n > 0 and k.outcome.feasible]
        for kappa in sorted(kappas, key=lambda k: (k.q, k.n), reverse=True):
            if _reaches_progress(tree, domain, kappa.outcome.state, baseline):
                # a feasible κ child is keyed by its sampled action
                best = (cont.q, cont.n, cast(Action, kappa.kappa))
                break
    return None if best is None else best[2]


def _reaches_progress(tree: SearchTree, domain: Domain, start: State, baseline: int) -> bool:
    """Whether ``start`` or a state the tree reaches from it (by feasible, visited κ) has
    more than ``baseline`` goal conjuncts true."""
    seen: set[State] = set()
    frontier = [start]
    while frontier:
        state = frontier.pop()
        if state in seen:
            continue
        seen.add(state)
        if domain.goal_atoms_true(state) > baseline:
            return True
        if state not in tree:
            continue
        for cont in tree.node(state).children:
            frontier.extend(
                k.outcome.state for k in cont.children if k.n > 0 and k.outcome.feasible
            )
    return False
