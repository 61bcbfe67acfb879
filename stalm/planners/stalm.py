"""STaLM (Algorithm 1), run online as the authors ran it, with what this implementation adds.

Each real step: compute the state's predicates (Appendix A's cache after the first step), ask
the proposer for N_batch task plans, Concretize them (Algorithm 2); if one reaches the goal,
execute it; otherwise run WarmStartedUCT (Algorithms 3–5) warm-started with everything
Concretize explored; if a simulation reaches the goal, execute that plan, else execute one
root action and plan again from the resulting state. One wall-clock deadline covers the whole
trial and is honoured between simulations. The executed plan is replayed in a fresh scene at
the end; a plan that fails there is a failure, never a success.

Beyond the paper, each a setting of :class:`StalmSettings` with the paper's way one switch
away:

* **tree reuse** (the authors' loop): the executed child's subtree is the next step's tree, so
  statistics accumulate over the episode instead of resting on one step's simulations;
* **geometric feedback**: the steps Concretize found infeasible go back to the proposer
  (:mod:`stalm.planners.feedback`), which is asked again in the same step while it learns
  something new and the step's share of the time lasts;
* **the execution rule**: without a goal plan, 'progress' executes the highest-Q root action
  from which the tree knows a way to more goal conjuncts than the root has, and while no
  root action does, searches on from the same root (within the step's share), rather than
  spending an irreversible step of the horizon on a coin toss ('best_q', the authors' rule).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Literal, cast

import numpy as np

from stalm.domain.actions import DiscreteAction
from stalm.domain.mdp import Domain, RewardSettings
from stalm.domain.params import Action
from stalm.errors import StalmError
from stalm.planners.base import PlanResult
from stalm.planners.episode import Episode, run_episode
from stalm.planners.feedback import FeedbackMemory, failed_steps
from stalm.planners.hcount import HcountLeafValue
from stalm.planners.proposers import FeedbackProposer, TaskPlanProposer, takes_feedback
from stalm.planners.step_log import proposal_record, tree_record, warm_edges
from stalm.predicates.engine import PredicateEngine
from stalm.search import (
    ConcretePlan,
    ConcretizeResult,
    SearchPolicies,
    SearchSettings,
    SearchTree,
    TaskPlan,
    concretize,
    warm_started_uct,
)
from stalm.world.problem import Problem
from stalm.world.state import State

Progress = Callable[[str], None]


ExecutionRule = Literal["best_q", "progress"]
EXECUTION_RULES: tuple[str, ...] = ("best_q", "progress")


@dataclass(frozen=True)
class StalmSettings:
    """Appendix B: N_batch = 5, N_budget = 30, c = 50, PW (1.5, 0.15), γ = 0.99; and what
    this implementation adds beyond the paper (each can be switched back to the paper's way).
    """

    n_batch: int = 5
    search: SearchSettings = field(default_factory=SearchSettings)
    use_tree: bool = True
    """False gives 'STaLM w/o UCT' (Table 3): no simulations after Concretize."""
    leaf_value: str = "rollout"
    """'rollout' (STaLM, UCT) or 'hcount' (UCT-with-Hcount, Appendix C)."""
    reuse_tree: bool = True
    """Keep the executed child's subtree as the next step's tree (the authors' experiment
    loop); False starts every real step from a fresh tree."""
    feedback: bool = False
    """Geometric feedback (:mod:`stalm.planners.feedback`): Concretize's failed steps go back
    to the proposer, which is asked again while the step's share of the budget lasts. Off
    for the paper's rows."""
    feedback_rounds: int = 8
    """At most this many proposals per real step with feedback (the first one included)."""
    step_share: float = 0.25
    """A real step may spend at most this fraction of the trial's remaining time asking the
    proposer again (feedback) or searching on with no progress ('progress' rule)."""
    execution: ExecutionRule = "best_q"
    """What to execute when no goal plan was found: 'best_q' the highest-Q root action (the
    authors' rule); 'progress' the highest-Q root action from which the tree reaches more
    goal conjuncts than the root has, searching on (within ``step_share``) while none does."""
    kappa_tries: int = 1
    """κ draws per task-plan step in Concretize (Algorithm 2: 1; the authors' code: 3)."""
    backtracks: int = 0
    """Concretize draws a placement again when an object the plan put down is in the way of a
    later step, at most this many times per plan (0: Algorithm 2)."""
    rewards: RewardSettings = field(default_factory=RewardSettings)
    """R's constants (§4.1, with the potential-based −3 of the research notes)."""
    occlusion_predicates: bool = True
    """Compute PickOccludedBy/PlaceOccludedBy for the prompt. False for Table 4's arms whose
    prompt does not show them, so those arms do not pay for motion planning they never use."""

    def __post_init__(self) -> None:
        if self.execution not in EXECUTION_RULES:
            raise StalmError(
                f"unknown execution rule '{self.execution}' "
                f"(available: {', '.join(EXECUTION_RULES)})"
            )
        if self.kappa_tries < 1:
            raise StalmError(f"kappa_tries must be at least 1, got {self.kappa_tries}")
        if self.feedback_rounds < 1:
            raise StalmError(f"feedback_rounds must be at least 1, got {self.feedback_rounds}")
        if not 0.0 < self.step_share <= 1.0:
            raise StalmError(f"step_share must be in (0, 1], got {self.step_share}")

    @property
    def needs_occlusion(self) -> bool:
        """Whether the predicate engine must plan occlusions: for the prompt, or for Hcount."""
        return self.occlusion_predicates or self.leaf_value == "hcount"


@dataclass
class StalmPlanner:
    """STaLM with any task-plan proposer (a language model by default)."""

    proposer: TaskPlanProposer | None
    """None runs the same online loop with no task plans: plain hybrid UCT (the 'uct' baseline)."""
    settings: StalmSettings = field(default_factory=StalmSettings)
    progress: Progress | None = None

    @property
    def name(self) -> str:
        if self.proposer is None:
            return "uct-hcount" if self.settings.leaf_value == "hcount" else "uct"
        return "stalm" if self.settings.use_tree else "stalm-no-uct"

    def _policies(self, problem: Problem, engine: PredicateEngine) -> SearchPolicies:
        policies = SearchPolicies.from_settings(self.settings.search)
        if self.settings.leaf_value == "hcount":
            return replace(policies, value=HcountLeafValue(problem, engine))
        return policies

    def _say(self, message: str) -> None:
        if self.progress is not None:
            self.progress(message)

    def solve(self, problem: Problem, seed: int, time_budget_s: float | None = None) -> PlanResult:
        return run_episode(
            problem, time_budget_s, lambda d, e: self._run(d, e, seed), self.settings.rewards
        )

    def _run(self, domain: Domain, episode: Episode, seed: int) -> PlanResult:
        problem = episode.problem
        engine = PredicateEngine(
            problem, domain.sim, domain.base_planner, occlusion=self.settings.needs_occlusion
        )
        trial = _Trial(self, domain, episode, engine, np.random.default_rng(seed), seed)
        termination = trial.run()
        details: dict[str, object] = {
            "proposer": self.proposer.name if self.proposer is not None else None,
            "settings": {
                "reuse_tree": self.settings.reuse_tree,
                "feedback": self.settings.feedback,
                "execution": self.settings.execution,
                "kappa_tries": self.settings.kappa_tries,
                "backtracks": self.settings.backtracks,
                "goal_atom_lost": self.settings.rewards.goal_atom_lost,
            },
            "proposals": trial.proposals,
            "feedback_steps_learned": len(trial.memory.steps),
            "reused_root_visits": trial.reused_root_visits,
            "steps": trial.step_records,
            "step_log": trial.step_log,
        }
        if isinstance(trial.policies.value, HcountLeafValue):
            details["hcount_leaves"] = {
                "predicates_from_scratch": trial.policies.value.computed_from_scratch,
                "predicates_brought_forward": trial.policies.value.brought_forward,
            }
        return episode.finish(
            domain,
            self.name,
            seed,
            termination,
            simulations=trial.simulations,
            replans=trial.replans,
            details=details,
        )


@dataclass
class _Trial:
    """One STaLM trial's loop and its bookkeeping (the tree kept between steps, what the
    proposer was told, counters)."""

    planner: StalmPlanner
    domain: Domain
    episode: Episode
    engine: PredicateEngine
    rng: np.random.Generator
    seed: int
    memory: FeedbackMemory = field(default_factory=FeedbackMemory.empty)
    tree: SearchTree | None = None
    simulations: int = 0
    replans: int = 0
    proposals: int = 0
    reused_root_visits: list[int] = field(default_factory=list)
    step_records: list[dict[str, object]] = field(default_factory=list)
    step_log: list[dict[str, Any]] = field(default_factory=list)
    """Per real step: the task plans and their fate, the tree, the decision
    (:mod:`stalm.planners.step_log`)."""
    _step: dict[str, Any] = field(default_factory=dict)
    """The current step's entry of ``step_log``."""

    def __post_init__(self) -> None:
        self.settings = self.planner.settings
        proposer = self.planner.proposer
        if self.settings.feedback and proposer is not None and not takes_feedback(proposer):
            raise StalmError(
                f"the proposer {proposer.name} takes no feedback (its propose() has no "
                "'feedback' parameter): switch feedback off"
            )
        self.policies = self.planner._policies(self.episode.problem, self.engine)

    def run(self) -> str:
        episode, domain = self.episode, self.domain
        while (termination := episode.stop_reason(domain)) is None:
            self.replans += 1
            self._step = {"step": len(episode.executed), "proposals": [], "tree": None}
            self.step_log.append(self._step)
            plans, solution = self._propose_and_concretize()
            if episode.out_of_time() and solution is None:
                self._step["decision"] = "timeout"
                return "timeout"
            if solution is not None:
                self._step["decision"] = "concretize_goal"
            to_execute = solution if solution is not None else self._decide(plans)
            self._step["executed"] = len(to_execute)
            # nothing feasible found: ask again from the same state
            for action in to_execute:
                before = episode.state
                episode.execute(domain, action)
                self._advance_tree(before, action)
                self.planner._say(f"executed {action.discrete}")
        return termination

    # ------------------------------------------------------------------ proposals
    def _propose_and_concretize(self) -> tuple[list[ConcretePlan], tuple[Action, ...] | None]:
        """Task plans from the proposer, concretized; with feedback, ask again while the
        failures teach something new and the step's share of the time lasts."""
        planner, episode, domain = self.planner, self.episode, self.domain
        proposer = planner.proposer
        state = episode.state
        done = len(episode.executed)
        if proposer is None:
            return [], None
        self.planner._say(f"step {done}: predicates")
        predicates = episode.predicates(self.engine)
        share_end = self._share_end()
        plans: list[ConcretePlan] = []
        tried: set[tuple[DiscreteAction, ...]] = set()
        for round_ in range(self.settings.feedback_rounds if self.settings.feedback else 1):
            feedback = self.memory.holding_in(state) if self.settings.feedback else ()
            planner._say(f"step {done}: asking {proposer.name} for task plans")
            query_seed = self.seed * 1000 + self.proposals
            if feedback:
                assert takes_feedback(proposer)
                proposal = cast(FeedbackProposer, proposer).propose(
                    episode.problem,
                    state,
                    predicates.literals,
                    self.settings.n_batch,
                    query_seed,
                    deadline=episode.deadline,
                    feedback=feedback,
                )
            else:
                proposal = proposer.propose(
                    episode.problem,
                    state,
                    predicates.literals,
                    self.settings.n_batch,
                    query_seed,
                    deadline=episode.deadline,
                )
            self.proposals += 1
            episode.record_query(proposal)
            if episode.out_of_time():
                return plans, None
            task_plans = [TaskPlan(plan) for plan in proposal.plans]
            task_plans += [TaskPlan.unreadable(reason) for reason in proposal.unparseable]
            tick = time.monotonic()
            planner._say(f"step {done}: concretizing {len(task_plans)} task plans")
            concrete = concretize(
                domain,
                state,
                task_plans,
                self.rng,
                depth0=done,
                horizon=episode.problem.horizon,
                kappa_tries=self.settings.kappa_tries,
                backtracks=self.settings.backtracks,
            )
            episode.clock.concretize += time.monotonic() - tick
            episode.count_failures(concrete)
            self._step["proposals"].append(
                proposal_record(round_, len(feedback), concrete.plans, predicates.literals)
            )
            plans.extend(concrete.plans)
            if concrete.success and concrete.solution is not None:
                return plans, concrete.solution
            if not self.settings.feedback or not proposal.plans:
                break
            learned = self.memory.learn(failed_steps(episode.problem, concrete.plans))
            self._record_round(done, round_, concrete, learned)
            fresh = {plan.task_plan.actions for plan in concrete.plans} - tried
            tried |= fresh
            # ask again while the proposer still comes up with plans not tried in this step
            # (a lesson learned, or a different draw failing where no lesson could be drawn)
            if not fresh or time.monotonic() >= share_end:
                break
        return plans, None

    def _record_round(
        self, done: int, round_: int, concrete: ConcretizeResult, learned: int
    ) -> None:
        self.step_records.append(
            {
                "step": done,
                "round": round_,
                "plans": len(concrete.plans),
                "failures": [kind for _, kind in concrete.failures],
                "facts_learned": learned,
            }
        )

    def _share_end(self) -> float:
        now = time.monotonic()
        return now + self.settings.step_share * max(0.0, self.episode.deadline - now)

    # ------------------------------------------------------------------ search and choice
    def _decide(self, plans: list[ConcretePlan]) -> tuple[Action, ...]:
        """What to execute when Concretize reached no goal: the tree's goal plan if the search
        finds one, else one root action chosen by the execution rule."""
        if not self.settings.use_tree:
            self._step["decision"] = "best_prefix"
            return _first_action_of_best_prefix(plans)
        episode, domain = self.episode, self.domain
        state = episode.state
        done = len(episode.executed)
        search = self.settings.search
        if self.tree is None or self.tree.root != state:
            self.tree = SearchTree.for_root(domain, state)
        tree, visits_before = self.tree, self.tree.visits(state)
        share_end = self._share_end()

        def decided(how: str) -> None:
            self._step["decision"] = how
            self._step["tree"] = tree_record(tree, warm_edges(plans), visits_before)

        warm = plans
        while True:
            tick = time.monotonic()
            self.planner._say(f"step {done}: warm-started UCT, {search.budget} simulations")
            result = warm_started_uct(
                domain,
                state,
                warm,
                self.rng,
                settings=search,
                depth0=done,
                deadline=episode.deadline,
                policies=self.policies,
                tree=self.tree,
            )
            episode.clock.tree += time.monotonic() - tick
            self.simulations += result.counters.simulations
            if result.goal_plan:
                decided("tree_goal")
                return result.goal_plan
            if result.best_action is None:
                decided("nothing")
                return ()
            if self.settings.execution == "best_q":
                decided("best_q")
                return (result.best_action,)
            promising = _best_promising_action(self.tree, domain)
            if promising is not None:
                decided("progress")
                return (promising,)
            if (
                result.stop_reason == "deadline"
                or time.monotonic() >= share_end
                or search.budget == 0
            ):
                decided("best_q_fallback")
                return (result.best_action,)
            warm = []

    def _advance_tree(self, before: State, action: Action) -> None:
        """Tree reuse: the executed action's child becomes the root, with its statistics."""
        tree = self.tree
        self.tree = None
        if tree is None or not self.settings.reuse_tree or tree.root != before:
            return
        after = self.episode.state
        if after in tree:
            self.tree = tree.subtree(after)
            self.reused_root_visits.append(self.tree.visits(after))


def _best_promising_action(tree: SearchTree, domain: Domain) -> Action | None:
    """The 'progress' rule: the highest-Q root action whose subtree holds a state with more
    goal conjuncts true than the root (the tree knows a way on from it to goal progress),
    with its highest-Q feasible κ; None if no root action leads to progress."""
    root = tree.node(tree.root)
    baseline = domain.goal_atoms_true(tree.root)
    best: tuple[float, int, Action] | None = None
    for cont in root.children:
        kappas = [k for k in cont.children if k.n > 0 and k.outcome.feasible]
        if not kappas:
            continue
        kappa = max(kappas, key=lambda k: (k.q, k.n))
        if best is not None and (cont.q, cont.n) <= best[:2]:
            continue
        if _reaches_progress(tree, domain, kappa.outcome.state, baseline):
            # a feasible κ child is keyed by its sampled action
            best = (cont.q, cont.n, cast(Action, kappa.kappa))
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


def _first_action_of_best_prefix(plans: object) -> tuple[Action, ...]:
    """STaLM w/o UCT: the first action of the task plan that got furthest."""
    best: tuple[Action, ...] = ()
    for plan in plans:  # type: ignore[attr-defined]
        actions = plan.actions
        if len(actions) > len(best):
            best = actions
    return best[:1]
