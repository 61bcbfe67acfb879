"""One real step of the tree planners: STaLM, STaLM w/o UCT, UCT and UCT-with-Hcount.

These four end a real step alike: without a plan that reached the goal, they run (warm-started)
UCT from the current state and execute what the execution rule chooses
(:meth:`SearchStep.search`; STaLM w/o UCT takes the best plan's first action instead). UCT's
step is only that (:meth:`SearchStep.decide`); STaLM's first gets task plans and Concretizes
them (:meth:`stalm.planners.stalm.StalmStep.decide`). Each step fills a record of what it
did (:class:`~stalm.trial.step_log.StepRecord`). :class:`SearchStep` is the shared step;
:class:`StalmSettings` what it reads of the run's settings tree, which holds the paper's values
and what this implementation adds:

* **tree reuse** (the authors' loop): the executed child's subtree is the next step's tree
  (:meth:`stalm.trial.online.Trial.execute`), so statistics accumulate over the episode;
* **the execution rule**: without a goal plan, 'progress' executes the highest-Q root action
  from which the tree knows a way to more goal conjuncts than the root has, and while no
  root action does, searches on from the same root (at most ``search_rounds`` searches: a
  count, so that the same seed decides the same on any machine), rather than spending an
  irreversible step of the horizon on a coin toss ('best_q', the authors' rule).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Any, cast

from stalm.domain.mdp import Domain, RewardSettings
from stalm.domain.params import Action
from stalm.search import ConcretePlan, SearchPolicies, SearchSettings, SearchTree, warm_started_uct
from stalm.settings.tree import ExecutionRule, RunSettings
from stalm.trial.online import ConfiguredPlanner, Decision, Trial
from stalm.trial.step_log import DECISIONS, StepRecord, tree_record, warm_edges
from stalm.world.state import State

log = logging.getLogger(__name__)
"""Each real step's search and the rule that chose what it executes, at INFO."""


@dataclass(frozen=True)
class StalmSettings:
    """What the tree planners read of a run's settings tree, typed and resolved for one
    planner: Appendix B's N_batch, N_budget, c, PW and γ, and what this implementation adds
    beyond the paper (each can be switched back to the paper's way in the tree).

    A view with no defaults of its own: :meth:`of` builds it from a
    :class:`~stalm.settings.tree.RunSettings`, whose sections hold every default and
    check every value, so a planner built by hand runs what ``stalm solve`` runs.
    """

    n_batch: int
    """N_batch: task plans per query (``search.batch``)."""
    search: SearchSettings
    """The search's constants with this planner's N_budget (``search``)."""
    reuse_tree: bool
    """Keep the executed child's subtree as the next step's tree (the authors' experiment
    loop); False starts every real step from a fresh tree."""
    feedback: bool
    """Geometric feedback (:mod:`stalm.proposers.feedback`): Concretize's failed steps go back
    to the proposer, which is asked again while it offers task plans not yet tried in the
    step (at most ``feedback_rounds`` times)."""
    feedback_rounds: int
    """At most this many proposals per real step with feedback (the first one included)."""
    search_rounds: int
    """'progress' rule: at most this many searches from one root before the best-Q fallback
    (a count, so that decisions do not depend on the machine's speed)."""
    step_share: float
    """A real step may spend at most this fraction of the trial's remaining time asking the
    proposer again (feedback) or searching on with no progress ('progress' rule); 1.0: no
    guard but the trial's deadline."""
    execution: ExecutionRule
    """What to execute when no goal plan was found: 'best_q' the highest-Q root action (the
    authors' rule); 'progress' the highest-Q root action from which the tree reaches more
    goal conjuncts than the root has, searching on (at most ``search_rounds`` searches) while
    none does."""
    kappa_tries: int
    """κ draws per task-plan step in Concretize (Algorithm 2: 1; the authors' code: 3)."""
    backtracks: int
    """Concretize draws a placement again when an object the plan put down is in the way of a
    later step, at most this many times per plan (0: Algorithm 2)."""
    rewards: RewardSettings
    """R's constants (§4.1, with this implementation's potential-based −3 for an undone goal
    conjunct)."""
    occlusion_predicates: bool
    """Compute PickOccludedBy/PlaceOccludedBy: for the prompt (False for Table 4's arms whose
    prompt does not show them, so those arms do not pay for motion planning they never use)
    or for Hcount (always on for UCT-with-Hcount)."""

    @classmethod
    def of(cls, settings: RunSettings, planner: str, *, proposes: bool) -> StalmSettings:
        """The settings tree planner ``planner`` reads from ``settings`` (a planner that
        ``proposes`` no task plans -- UCT -- gets no feedback; UCT-with-Hcount always
        computes the occlusion predicates its heuristic reads)."""
        feedback = settings.feedback()
        execution = settings.execution
        return cls(
            n_batch=settings.search.batch,
            search=settings.search.search_settings(settings.search.budget_for(planner)),
            reuse_tree=execution.reuse_tree,
            feedback=feedback and proposes,
            feedback_rounds=execution.feedback_rounds,
            search_rounds=execution.search_rounds,
            step_share=execution.step_share,
            execution=execution.rule,
            kappa_tries=execution.kappa_tries,
            backtracks=execution.backtracks_for(feedback),
            rewards=settings.rewards,
            # the symbolic proposer plans with occlusions whatever the prompt options say,
            # the noisy one needs them to drop the step that clears an occluder, and Hcount
            # reads them at every leaf
            occlusion_predicates=(
                planner == "uct-hcount"
                or settings.proposer.kind != "llm"
                or settings.prompt.occlusion_predicates
            ),
        )


class TreePlanner(ConfiguredPlanner):
    """An online planner configured by :class:`StalmSettings` (STaLM, UCT and their
    variants): R's constants, the occlusion predicates and tree reuse come from there."""

    settings: StalmSettings


class SearchStep:
    """UCT's real step, and the search every tree planner's step ends in (see the module
    docstring). Each step's :class:`StepRecord` is made by :meth:`begin` and handed to the
    parts of the step that fill it in."""

    def __init__(self, trial: Trial, settings: StalmSettings, policies: SearchPolicies) -> None:
        self.trial = trial
        self.settings = settings
        self.policies = policies
        self.step_log: list[StepRecord] = []
        """Per real step: the task plans and their fate, the tree, the decision
        (:mod:`stalm.trial.step_log`)."""

    def begin(self) -> StepRecord:
        """A new real step: counted, and its record added to the log."""
        self.trial.replans += 1
        record = StepRecord(self.trial.done)
        self.step_log.append(record)
        return record

    def decide(self) -> Decision:
        """UCT's step: search from the current state, execute what the execution rule
        chooses."""
        record = self.begin()
        if self.trial.out_of_time():
            record.decision = "timeout"
            return "timeout"
        to_execute = self.search([], record)
        record.executed = len(to_execute)
        # nothing feasible found (an empty plan): the loop asks again from the same state
        return to_execute

    def details(self) -> dict[str, Any]:
        return {
            "proposer": None,
            "settings": {
                "reuse_tree": self.settings.reuse_tree,
                "feedback": self.settings.feedback,
                "execution": self.settings.execution,
                "kappa_tries": self.settings.kappa_tries,
                "backtracks": self.settings.backtracks,
                "goal_atom_lost": self.settings.rewards.goal_atom_lost,
            },
            "proposals": 0,
            "feedback_steps_learned": 0,
            "reused_root_visits": self.trial.reused_root_visits,
            "step_log": [record.to_json() for record in self.step_log],
        }

    def share_end(self) -> float:
        """When this step's share of the trial's remaining time runs out."""
        now = time.monotonic()
        return now + self.settings.step_share * max(0.0, self.trial.episode.deadline - now)

    def search(self, plans: list[ConcretePlan], record: StepRecord) -> tuple[Action, ...]:
        """The tree's goal plan if the search (warm-started with ``plans``) finds one, else
        one root action chosen by the execution rule; ``record`` is told which, and how the
        tree looks after the search."""
        trial = self.trial
        domain, state, done = trial.domain, trial.state, trial.done
        search = trial.within_horizon(self.settings.search)
        tree = trial.tree_at(state)
        visits_before = tree.visits(state)
        share_end = self.share_end()

        searches = 0

        def decided(how: str) -> None:
            record.decision = how
            record.searches = searches
            record.tree = tree_record(tree, warm_edges(plans), visits_before)
            log.info("step %d: %d search(es): %s", done, searches, DECISIONS.get(how, how))

        warm = plans
        while True:
            searches += 1
            trial.say(f"step {done}: warm-started UCT, {search.budget} simulations")
            with trial.phase("tree"):
                result = warm_started_uct(
                    domain,
                    state,
                    warm,
                    trial.rng,
                    settings=search,
                    depth0=done,
                    deadline=trial.episode.deadline,
                    policies=self.policies,
                    tree=tree,
                )
            trial.simulations += result.counters.simulations
            if result.goal_plan:
                decided("tree_goal")
                return result.goal_plan
            if result.best_action is None:
                decided("nothing")
                return ()
            if self.settings.execution == "best_q":
                decided("best_q")
                return (result.best_action,)
            promising = _best_promising_action(tree, domain)
            if promising is not None:
                decided("progress")
                return (promising,)
            if (
                result.stop_reason == "deadline"
                or searches >= self.settings.search_rounds
                or time.monotonic() >= share_end
                or search.budget == 0
            ):
                decided("best_q_fallback")
                return (result.best_action,)
            warm = []


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
