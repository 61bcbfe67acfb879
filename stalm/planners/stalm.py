"""STaLM (Algorithm 1), run online as the authors ran it, with what this implementation adds.

:meth:`StalmStep.decide` is one real step in the paper's words, top to bottom: CreatePrompt
and the proposer's task plans, Concretize (Algorithm 2), a plan that reached the goal executed
whole, else WarmStartedUCT (Algorithms 3-5, :func:`~stalm.planners.tree_step.search`, shared
with UCT) warm-started with what Concretize explored, and its plan or one root action
executed. What the step records on the way is :class:`ProposalAccount`'s; the trial itself
(one deadline, the executed plan, its replay in a fresh scene) is
:class:`~stalm.trial.online.OnlinePlanner`'s.

Beyond the paper, each one switch away from the paper's way in the run's settings tree: tree
reuse and the execution rule (:mod:`stalm.planners.tree_step`), and **geometric feedback**:
the steps Concretize found infeasible go back to the proposer (:mod:`stalm.proposers.feedback`),
asked again in the same step while it offers task plans not yet tried there.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace

from stalm.domain.actions import DiscreteAction
from stalm.domain.params import Action
from stalm.errors import StalmError
from stalm.planners.registry_rows import planner_rows
from stalm.planners.tree_step import TreeDetails, begin_step, search, tree_details, tree_planner
from stalm.predicates.literals import GroundLiteral
from stalm.progress import Progress
from stalm.proposers.fast_downward import SymbolicProposer
from stalm.proposers.feedback import FailedStep, failed_steps
from stalm.proposers.feedback_memory import FeedbackMemory, grounded_in_tree, grounded_steps
from stalm.proposers.language_model import model_proposer
from stalm.proposers.noisy import InjectedPlan, NoisyProposer, injected_records
from stalm.proposers.protocol import Proposal, ProposalRequest, TaskPlanProposer, check_proposer
from stalm.search import ConcretePlan, ConcretizeResult, SearchPolicies, TaskPlan, concretize
from stalm.settings.tree import ProposerKind, RunSettings
from stalm.trial.online import Decision, OnlinePlanner, Trial
from stalm.trial.query_seeds import stalm_proposal_seed
from stalm.trial.step_log import RoundLessons, StepRecord, proposal_record

log = logging.getLogger(__name__)
"""Each proposal round's plans and what Concretize made of them, at INFO."""

NoGoalPlan = Callable[["StalmStep", list[ConcretePlan], StepRecord], tuple[Action, ...]]
"""What a step executes when no task plan reached the goal (STaLM: :func:`warm_started_search`;
STaLM w/o UCT: the best plan's first action); it says why in the step's record."""


@dataclass
class StalmStep:
    """STaLM's real step, Algorithm 1's body from the current state s, read top to bottom in
    :meth:`decide` and :meth:`propose_and_concretize`; what it records on the way (progress,
    queries, noise, the step log) is its :class:`ProposalAccount`'s."""

    trial: Trial
    settings: RunSettings
    policies: SearchPolicies
    account: ProposalAccount
    """The proposer, asked through the record of its queries."""
    no_goal_plan: NoGoalPlan
    memory: FeedbackMemory = field(default_factory=FeedbackMemory.empty)
    """What the proposer was told (geometric feedback)."""
    step_log: list[StepRecord] = field(default_factory=list)

    def decide(self) -> Decision:
        """Task plans for s, concretized (L2-3); one that reached the goal is executed whole
        (L4-5); else WarmStartedUCT, warm-started with what Concretize grounded, decides what
        to execute (L6-7)."""
        record = begin_step(self.trial, self.step_log)
        plans, solution = self.propose_and_concretize(record)
        if solution is not None:
            return record.executes(solution, "concretize_goal")
        if self.trial.episode.out_of_time():
            return record.timed_out()
        # nothing feasible found (an empty plan): the loop asks again from the same state
        return record.executes(self.no_goal_plan(self, plans, record))

    def propose_and_concretize(
        self, record: StepRecord
    ) -> tuple[list[ConcretePlan], tuple[Action, ...] | None]:
        """TaskPlans <- QueryLLM(CreatePrompt(s, G), N_batch); success, Plans <-
        Concretize(TaskPlans, s, h). With feedback, the steps Concretize found infeasible are
        learned and the proposer asked again (at most ``feedback_rounds`` times) while it
        offers plans not yet tried in this step."""
        trial, execution, account = self.trial, self.settings.execution, self.account
        learns = self.settings.feedback()
        trial.say(f"step {trial.done}: predicates")
        literals = trial.episode.predicates().literals
        step_end = trial.share_end(execution.step_share)
        plans: list[ConcretePlan] = []
        tried: set[tuple[DiscreteAction, ...]] = set()
        for round_ in range(execution.feedback_rounds if learns else 1):
            feedback = self.memory.holding_in(trial.episode.state) if learns else ()
            proposal = account.query(self.create_prompt(literals, feedback))
            if trial.episode.out_of_time():
                return plans, None
            concrete = self.concretize(proposal, round_)
            account.concretized(record, round_, proposal, concrete, feedback, literals)
            plans.extend(concrete.plans)
            if concrete.success and concrete.solution is not None:
                return plans, concrete.solution
            if not learns or not proposal.plans:
                break
            record.learned(self.learn(concrete))
            fresh = {plan.task_plan.actions for plan in concrete.plans} - tried
            tried |= fresh
            # ask again while the proposer still comes up with plans not tried in this step
            # (a lesson learned, or a different draw failing where no lesson could be drawn)
            if not fresh or time.monotonic() >= step_end:
                break
        return plans, None

    def create_prompt(
        self, literals: frozenset[GroundLiteral], feedback: tuple[FailedStep, ...]
    ) -> ProposalRequest:
        """CreatePrompt(s, G): N_batch task plans for the current state, its predicates and
        what geometric feedback says holds there."""
        episode = self.trial.episode
        return ProposalRequest(
            episode.problem,
            episode.state,
            literals,
            self.settings.search.batch,
            stalm_proposal_seed(self.trial.seed, self.account.proposals),
            deadline=episode.deadline,
            feedback=feedback,
        )

    def concretize(self, proposal: Proposal, round_: int) -> ConcretizeResult:
        """Concretize(TaskPlans, s, h) (Algorithm 2) of every plan of ``proposal``, its
        unreadable replies and its reasons for no plan included (Figure 5 counts them)."""
        trial, settings = self.trial, self.settings
        task_plans = [TaskPlan(plan) for plan in proposal.plans]
        task_plans += [TaskPlan.unreadable(reason) for reason in proposal.unparseable]
        task_plans += [TaskPlan.none_found(reason) for reason in proposal.no_plan]
        self.account.concretizing(round_, len(task_plans))
        with trial.phase("concretize"):
            return concretize(
                trial.domain,
                trial.episode.state,
                task_plans,
                trial.rng,
                depth0=trial.done,
                horizon=trial.episode.problem.horizon,
                kappa_tries=settings.execution.kappa_tries,
                backtracks=settings.backtracks(),
            )

    def learn(self, concrete: ConcretizeResult) -> RoundLessons:
        """Geometric feedback from a round: its failed steps are learned, its grounded picks and
        placements refute rules; for the round's step-log entry, ``facts_learned`` counts the
        lessons not known before (a rule adds no PDDL fact), ``rules_refuted`` the rules."""
        problem = self.trial.episode.problem
        learned = self.memory.learn(failed_steps(problem, concrete.plans))
        refuted = self.memory.observe(grounded_steps(problem, concrete.plans))
        return RoundLessons(tuple(kind for _, kind in concrete.failures), learned, refuted)

    def details(self) -> TreeDetails:
        account = self.account
        noisy = account.proposer if isinstance(account.proposer, NoisyProposer) else None
        return replace(
            tree_details(
                self.trial, self.settings, self.step_log, feedback=self.settings.feedback()
            ),
            proposer=account.proposer.name,
            proposals=account.proposals,
            feedback_steps_learned=len(self.memory.steps),
            noise=None if noisy is None else noisy.record(account.injected),
        )


def warm_started_search(
    step: StalmStep, plans: list[ConcretePlan], record: StepRecord
) -> tuple[Action, ...]:
    """WarmStartedUCT(Plans, s, h, N_budget) and the execution rule (:func:`search`); with
    feedback, the picks and placements its simulations found feasible then refute the rules
    that forbid them."""
    chosen = search(step.trial, step.settings, step.policies, plans, record)
    tree = step.trial.tree
    if step.settings.feedback() and tree is not None:
        problem = step.trial.episode.problem
        record.rules_refuted_by_tree = step.memory.observe(grounded_in_tree(problem, tree))
    return chosen


@dataclass
class ProposalAccount:
    """STaLM's proposer with what its step records around each query, so that the step reads
    as Algorithm 1: progress, the query's cost, the failure kinds, the noisy proposer's
    injections, each round's entry of the step log. The step reads back only the count of
    proposals (the next query's seed)."""

    trial: Trial
    proposer: TaskPlanProposer
    proposals: int = 0
    injected: list[InjectedPlan] = field(default_factory=list)
    """The noisy proposer's plans: what was injected into each, and its Figure 5 kind."""

    def query(self, request: ProposalRequest) -> Proposal:
        """QueryLLM: the proposer's answer to ``request``, announced and recorded."""
        name = self.proposer.name
        self.trial.say(f"step {self.trial.done}: asking {name} for task plans")
        self.trial.episode.observer.proposal(self.proposals, name)
        proposal = self.proposer.propose(request)
        self.proposals += 1
        self.trial.episode.record_query(proposal)
        return proposal

    def concretizing(self, round_: int, plans: int) -> None:
        self.trial.say(f"step {self.trial.done}: concretizing {plans} task plans")
        self.trial.episode.observer.concretize(round_, plans)

    def concretized(
        self,
        record: StepRecord,
        round_: int,
        proposal: Proposal,
        concrete: ConcretizeResult,
        feedback: tuple[FailedStep, ...],
        literals: Iterable[GroundLiteral],
    ) -> None:
        """Round ``round_``'s failure kinds, injections and entry of the step log (a
        feedback round adds what it learned: :meth:`StepRecord.learned`)."""
        done = self.trial.done
        self.trial.episode.count_failures(concrete)
        if proposal.injected:
            self.injected += injected_records(
                done, round_, proposal.injected, concrete.plans, literals
            )
        entry = proposal_record(round_, len(feedback), concrete.plans, literals, proposal.set_aside)
        record.proposals.append(entry)
        log.info(
            "step %d, round %d: %s offered %d task plan(s)%s; %s",
            done,
            round_,
            self.proposer.name,
            len(proposal.plans) + len(proposal.unparseable) + len(proposal.no_plan),
            f" after {len(feedback)} feedback fact(s)" if feedback else "",
            concretize_summary(concrete),
        )


def concretize_summary(concrete: ConcretizeResult) -> str:
    """What Concretize made of a round's task plans, in a few words (for the log)."""
    if concrete.success:
        return "one reached the goal"
    counted = Counter(kind for _, kind in concrete.failures)
    kinds = ", ".join(f"{n} {kind}" for kind, n in counted.items())
    return "none reached the goal" + (f" ({kinds})" if kinds else "")


def best_prefix_first_action(
    step: StalmStep, plans: list[ConcretePlan], record: StepRecord
) -> tuple[Action, ...]:
    """STaLM w/o UCT's decision without a goal plan (Table 3's ablation, no search after
    Concretize): the first action of the task plan that got furthest (the first of equally
    long ones)."""
    record.decision = "best_prefix"
    return max((plan.actions for plan in plans), key=len, default=())[:1]


@dataclass(frozen=True)
class StalmSteps:
    """STaLM's part of a planner: the proposer, what its steps read of the settings tree and
    what they execute without a goal plan; called at a trial's start, its steps."""

    proposer: TaskPlanProposer
    settings: RunSettings
    no_goal_plan: NoGoalPlan = warm_started_search

    def __call__(self, trial: Trial) -> StalmStep:
        proposer = self.proposer
        if self.settings.feedback() and not proposer.takes_feedback:
            raise StalmError(
                f"the proposer {proposer.name} takes no feedback (its takes_feedback is false): "
                "switch feedback off"
            )
        policies = SearchPolicies.from_settings(self.settings.search.search_settings())
        account = ProposalAccount(trial, proposer)
        return StalmStep(trial, self.settings, policies, account, self.no_goal_plan)


def StalmPlanner(
    proposer: TaskPlanProposer,
    settings: RunSettings | None = None,
    progress: Progress | None = None,
    *,
    name: str = "stalm",
    no_goal_plan: NoGoalPlan = warm_started_search,
) -> OnlinePlanner:
    """STaLM with any task-plan proposer, configured by a run's settings tree.

    ``settings`` is that tree (None: its defaults). The proposer given is the one that runs,
    so it decides the tree's ``proposer.kind`` (:func:`proposer_kind`) and with it the
    defaults that depend on the proposer (feedback and backtracks):
    ``StalmPlanner(SymbolicProposer())`` runs what ``stalm solve --proposer symbolic`` runs.
    The registry builds STaLM w/o UCT with its ``name`` and :func:`best_prefix_first_action`.
    """
    check_proposer(proposer)
    run_settings = settings or RunSettings()
    section = replace(run_settings.proposer, kind=proposer_kind(proposer))
    # N_budget: STaLM's row (STaLM w/o UCT's says the same)
    run_settings = planner_rows()["stalm"].settings_for(replace(run_settings, proposer=section))
    steps = StalmSteps(proposer, run_settings, no_goal_plan)
    return tree_planner(name, run_settings, steps, progress)


def proposer_kind(proposer: TaskPlanProposer) -> ProposerKind:
    """The settings tree's name for ``proposer``: 'symbolic' for Fast Downward, 'noisy' for
    the noisy proposer, 'llm' for any other (a language model or a proposer of one's own)."""
    if isinstance(proposer, SymbolicProposer):
        return "symbolic"
    return "noisy" if isinstance(proposer, NoisyProposer) else "llm"


def proposer_for(settings: RunSettings) -> TaskPlanProposer:
    """STaLM's proposer: the symbolic planner, the configured (cached) language model, or the
    noisy proposer wrapping one of them."""
    section = settings.proposer
    if section.kind == "noisy":
        noise = section.noise
        return NoisyProposer(_plain_proposer(settings, noise.inner), noise.rate, noise.weights)
    return _plain_proposer(settings, section.kind)


def _plain_proposer(settings: RunSettings, kind: str) -> TaskPlanProposer:
    if kind == "symbolic":
        return SymbolicProposer(
            goal_relations_only=settings.proposer.goal_relations_only,
            break_occlusion_cycles=settings.proposer.break_occlusion_cycles,
            needed_objects_only=settings.proposer.needed_objects_only,
        )
    return model_proposer(settings)
