"""STaLM (Algorithm 1), run online as the authors ran it, with what this implementation adds.

Each real step: compute the state's predicates (Appendix A's cache after the first step), ask
the proposer for N_batch task plans, Concretize them (Algorithm 2); if one reaches the goal,
execute it; otherwise run WarmStartedUCT (Algorithms 3–5) warm-started with everything
Concretize explored; if a simulation reaches the goal, execute that plan, else execute one
root action and plan again from the resulting state. :meth:`StalmStep.decide` is that step,
top to bottom; the search and its execution rule are
:meth:`~stalm.planners.tree_step.SearchStep.search`, shared with UCT. The trial itself -- one
deadline, the executed plan, its replay in a fresh scene -- is
:class:`~stalm.trial.online.OnlinePlanner`'s.

Beyond the paper, each a setting of the run's settings tree
(:class:`~stalm.settings.tree.RunSettings`, read through :class:`StalmSettings`) with the
paper's way one switch away: tree reuse and the execution rule
(:mod:`stalm.planners.tree_step`), and **geometric feedback**: the steps Concretize found
infeasible go back to the proposer (:mod:`stalm.proposers.feedback`), which is asked again in
the same step while it comes up with task plans not yet tried there (at most
``feedback_rounds`` proposals per step).
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from typing import Any, ClassVar

from stalm.domain.actions import DiscreteAction
from stalm.domain.params import Action
from stalm.errors import StalmError
from stalm.planners.tree_step import SearchStep, StalmSettings, TreePlanner
from stalm.progress import Progress
from stalm.proposers.fast_downward import SymbolicProposer
from stalm.proposers.feedback import failed_steps
from stalm.proposers.feedback_memory import FeedbackMemory, grounded_in_tree, grounded_steps
from stalm.proposers.language_model import LLMProposer
from stalm.proposers.model_backend import llm_backend, use_constraint
from stalm.proposers.noisy import NoisyProposer, injected_records
from stalm.proposers.protocol import ProposalRequest, TaskPlanProposer
from stalm.search import (
    ConcretePlan,
    ConcretizeResult,
    SearchPolicies,
    TaskPlan,
    concretize,
)
from stalm.settings.tree import ProposerKind, RunSettings
from stalm.trial.online import Decision, Sampling, Trial
from stalm.trial.query_seeds import stalm_proposal_seed
from stalm.trial.step_log import StepRecord, proposal_record

__all__ = ["StalmPlanner", "StalmSettings", "StalmStep"]

log = logging.getLogger(__name__)
"""Each proposal round's plans and what Concretize made of them, at INFO."""


class StalmStep(SearchStep):
    """STaLM's real step: task plans, Concretize, and the search when none reached the goal."""

    def __init__(
        self,
        trial: Trial,
        settings: StalmSettings,
        policies: SearchPolicies,
        proposer: TaskPlanProposer,
    ) -> None:
        super().__init__(trial, settings, policies)
        self.proposer = proposer
        self.memory = FeedbackMemory.empty()
        """What the proposer was told (geometric feedback)."""
        self.proposals = 0
        self.injected: list[dict[str, Any]] = []
        """The noisy proposer's plans: what was injected into each, and its Figure 5 kind."""

    def details(self) -> dict[str, Any]:
        details = {
            **super().details(),
            "proposer": self.proposer.name,
            "proposals": self.proposals,
            "feedback_steps_learned": len(self.memory.steps),
        }
        if isinstance(self.proposer, NoisyProposer):
            details["noise"] = {**self.proposer.describe(), "plans": self.injected}
        return details

    def decide(self) -> Decision:
        """Algorithm 1's loop body: task plans for the current state, concretized; a plan
        that reached the goal is executed whole, else WarmStartedUCT from the current state,
        warm-started with what Concretize grounded, decides what to execute."""
        record = self.begin()
        plans, solution = self.propose(record)
        if solution is not None:
            record.decision = "concretize_goal"
            to_execute = solution
        elif self.trial.out_of_time():
            record.decision = "timeout"
            return "timeout"
        else:
            to_execute = self.without_goal_plan(plans, record)
        record.executed = len(to_execute)
        # nothing feasible found (an empty plan): the loop asks again from the same state
        return to_execute

    def propose(self, record: StepRecord) -> tuple[list[ConcretePlan], tuple[Action, ...] | None]:
        """Task plans from the proposer, concretized; with feedback, ask again (at most
        ``feedback_rounds`` times) while the proposer offers plans not yet tried in this step.
        Each round's plans go into ``record``."""
        trial, proposer, settings = self.trial, self.proposer, self.settings
        episode, domain, state, done = trial.episode, trial.domain, trial.state, trial.done
        trial.say(f"step {done}: predicates")
        predicates = trial.predicates()
        share_end = self.share_end()
        plans: list[ConcretePlan] = []
        tried: set[tuple[DiscreteAction, ...]] = set()
        for round_ in range(settings.feedback_rounds if settings.feedback else 1):
            feedback = self.memory.holding_in(state) if settings.feedback else ()
            trial.say(f"step {done}: asking {proposer.name} for task plans")
            trial.observer.proposal(self.proposals, proposer.name)
            query_seed = stalm_proposal_seed(trial.seed, self.proposals)
            proposal = proposer.propose(
                ProposalRequest(
                    episode.problem,
                    state,
                    predicates.literals,
                    settings.n_batch,
                    query_seed,
                    deadline=episode.deadline,
                    feedback=tuple(feedback),
                )
            )
            self.proposals += 1
            episode.record_query(proposal)
            if episode.out_of_time():
                return plans, None
            task_plans = [TaskPlan(plan) for plan in proposal.plans]
            task_plans += [TaskPlan.unreadable(reason) for reason in proposal.unparseable]
            task_plans += [TaskPlan.none_found(reason) for reason in proposal.no_plan]
            trial.say(f"step {done}: concretizing {len(task_plans)} task plans")
            trial.observer.concretize(round_, len(task_plans))
            with trial.phase("concretize"):
                concrete = concretize(
                    domain,
                    state,
                    task_plans,
                    trial.rng,
                    depth0=done,
                    horizon=episode.problem.horizon,
                    kappa_tries=settings.kappa_tries,
                    backtracks=settings.backtracks,
                )
            episode.count_failures(concrete)
            if proposal.injected:
                self.injected += injected_records(
                    done, round_, proposal.injected, concrete.plans, predicates.literals
                )
            round_entry = proposal_record(
                round_, len(feedback), concrete.plans, predicates.literals
            )
            if proposal.set_aside:
                round_entry["set_aside"] = list(proposal.set_aside)
            record.proposals.append(round_entry)
            log.info(
                "step %d, round %d: %s offered %d task plan(s)%s; %s",
                done,
                round_,
                proposer.name,
                len(task_plans),
                f" after {len(feedback)} feedback fact(s)" if feedback else "",
                concretize_summary(concrete),
            )
            plans.extend(concrete.plans)
            if concrete.success and concrete.solution is not None:
                return plans, concrete.solution
            if not settings.feedback or not proposal.plans:
                break
            learned = self.memory.learn(failed_steps(episode.problem, concrete.plans))
            refuted = self.memory.observe(grounded_steps(episode.problem, concrete.plans))
            round_entry.update(feedback_round_record(concrete, learned, refuted))
            fresh = {plan.task_plan.actions for plan in concrete.plans} - tried
            tried |= fresh
            # ask again while the proposer still comes up with plans not tried in this step
            # (a lesson learned, or a different draw failing where no lesson could be drawn)
            if not fresh or time.monotonic() >= share_end:
                break
        return plans, None

    def without_goal_plan(
        self, plans: list[ConcretePlan], record: StepRecord
    ) -> tuple[Action, ...]:
        """No task plan reached the goal: the warm-started search decides
        (:meth:`SearchStep.search`); with feedback, the picks and placements its simulations
        found feasible then refute the rules that forbid them."""
        chosen = self.search(plans, record)
        tree = self.trial.tree
        if self.settings.feedback and tree is not None:
            refuted = self.memory.observe(grounded_in_tree(self.trial.episode.problem, tree))
            record.rules_refuted_by_tree = refuted
        return chosen


def concretize_summary(concrete: ConcretizeResult) -> str:
    """What Concretize made of a round's task plans, in a few words (for the log)."""
    if concrete.success:
        return "one reached the goal"
    kinds = [kind for _, kind in concrete.failures]
    if not kinds:
        return "none reached the goal"
    counted = {kind: kinds.count(kind) for kind in dict.fromkeys(kinds)}
    return "none reached the goal (" + ", ".join(f"{n} {k}" for k, n in counted.items()) + ")"


def feedback_round_record(concrete: ConcretizeResult, learned: int, refuted: int) -> dict[str, Any]:
    """What a feedback round taught, added to its proposal's entry of the step log:
    ``facts_learned`` counts the lessons (failed steps and rules) that were not known before,
    as :meth:`FeedbackMemory.learn` returns them (a rule adds no PDDL fact of its own), and
    ``rules_refuted`` the rules the round's grounded steps refuted."""
    return {
        "failures": [kind for _, kind in concrete.failures],
        "facts_learned": learned,
        "rules_refuted": refuted,
    }


class StalmPlanner(TreePlanner):
    """STaLM with any task-plan proposer, configured by a run's settings tree.

    ``settings`` is that tree (None: :class:`RunSettings`' defaults, which ``stalm solve``
    runs without overrides). The proposer given is the one that runs, so the tree's
    ``proposer.kind`` is taken to be its kind (:func:`proposer_kind`): that kind decides the
    defaults that depend on the proposer (feedback and backtracks), so
    ``StalmPlanner(SymbolicProposer())`` runs what ``stalm solve --proposer symbolic`` runs.
    ``settings`` on the planner is what its steps read of the tree (:class:`StalmSettings`).
    """

    name = "stalm"
    step_type: ClassVar[type[StalmStep]] = StalmStep
    """The real step this planner runs (STaLM w/o UCT: another decision without a goal plan)."""

    def __init__(
        self,
        proposer: TaskPlanProposer,
        settings: RunSettings | None = None,
        progress: Progress | None = None,
    ) -> None:
        run_settings = with_proposer_kind(settings or RunSettings(), proposer)
        self.proposer = proposer
        self.settings = StalmSettings.of(run_settings, self.name, proposes=True)
        self.sampling = Sampling.of(run_settings)
        self.progress = progress

    def start(self, trial: Trial) -> StalmStep:
        proposer = self.proposer
        if self.settings.feedback and not proposer.takes_feedback:
            raise StalmError(
                f"the proposer {proposer.name} takes no feedback (its takes_feedback is false): "
                "switch feedback off"
            )
        policies = SearchPolicies.from_settings(self.settings.search)
        return self.step_type(trial, self.settings, policies, proposer)


def proposer_kind(proposer: TaskPlanProposer) -> ProposerKind:
    """The settings tree's name for ``proposer``: 'symbolic' for Fast Downward, 'noisy' for
    the noisy proposer, 'llm' for any other (a language model or a proposer of one's own)."""
    if isinstance(proposer, SymbolicProposer):
        return "symbolic"
    if isinstance(proposer, NoisyProposer):
        return "noisy"
    return "llm"


def with_proposer_kind(settings: RunSettings, proposer: TaskPlanProposer) -> RunSettings:
    """``settings`` with ``proposer``'s kind as ``proposer.kind`` (itself if it is already)."""
    kind = proposer_kind(proposer)
    if settings.proposer.kind == kind:
        return settings
    return replace(settings, proposer=replace(settings.proposer, kind=kind))


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
    backend = llm_backend(settings)
    return LLMProposer(backend, settings.prompt, constrained=use_constraint(settings, backend))


def build_stalm(settings: RunSettings, progress: Progress | None) -> StalmPlanner:
    """The registry's builder."""
    return StalmPlanner(proposer_for(settings), settings, progress)
