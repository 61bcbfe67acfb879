"""Iterative-Replanning (§4.2, after Shinn et al., 2024): one plan per query, feedback on failure.

At a state: ask with STaLM's prompt (the state's predicates) for ONE task plan and Concretize it.
If it reaches the goal, execute it. If not, ask again with the same prompt plus up to the two most
recent failed plans, each with the step that failed and why (:mod:`stalm.llm.feedback_prompt`).
After ``attempts_per_state`` = 5 queries without a goal-reaching plan, execute the next action of
the most recent plan -- its first step, with the κ Concretize found feasible -- and continue from
the new state (predicates updated incrementally, as STaLM does). If that first step was not
feasible either, nothing is executed and the loop asks again from the same state.

Decisions written down here: the feedback memory holds plans tried from the *current* state and
is cleared when an action is executed, because a failure explained against an init that no
longer holds would mislead the model; every query's seed is derived from (trial seed, round,
attempt), a round being one series of up to five queries.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from stalm.domain.params import Action
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.backends.base import LLMBackend
from stalm.llm.feedback_prompt import MAX_FAILED_PLANS, FailedPlan, with_feedback
from stalm.llm.problem_prompt import problem_prompt
from stalm.llm.prompt import PromptOptions
from stalm.progress import Progress
from stalm.proposers.language_model import ask_for_task_plans
from stalm.proposers.model_backend import use_constraint
from stalm.search import TaskPlan, concretize
from stalm.search.concretize import ConcretePlan
from stalm.settings.tree import RunSettings
from stalm.trial.details import DirectRecord
from stalm.trial.online import Decision, OnlinePlanner, Trial
from stalm.trial.query_seeds import query_seed


@dataclass(frozen=True)
class ReplanningConstants:
    """Iterative-Replanning's own constants, which the settings tree does not hold (the
    paper's): 5 single-plan queries per state, 2 failed plans in the prompt, temperature 1."""

    attempts_per_state: int = 5
    max_failed_plans: int = MAX_FAILED_PLANS
    temperature: float = 1.0


@dataclass(frozen=True)
class ReplanningDetails(DirectRecord):
    """Iterative-Replanning's record of a trial: the model asked, its queries (and those that
    showed failed plans), the rounds of queries at a state, the steps forced after a round's
    failures."""

    backend: str
    queries: int
    queries_with_feedback: int
    rounds: int
    forced_steps: int


def failed_plan(plan: ConcretePlan) -> FailedPlan:
    """The feedback record of a task plan Concretize could not take to the goal."""
    kind = plan.failure or "partially_achieved_goal"
    reason = plan.detail or "the goal does not hold"
    if plan.failed_step is not None:
        why = plan.steps[plan.failed_step].infeasibility
        if why is not None:
            reason = why.detail if why.kind == "precondition" else str(why)
    return FailedPlan(plan.task_plan.actions, kind, reason, plan.failed_step)


@dataclass(frozen=True)
class Replanning:
    """Iterative-Replanning's part of a planner: the model, whether its replies are
    constrained, the prompt options and the method's own constants (which the settings tree
    does not hold); called at a trial's start, its rounds (:class:`ReplanningRounds`)."""

    backend: LLMBackend
    constrained: bool
    options: PromptOptions
    constants: ReplanningConstants = ReplanningConstants()

    def __call__(self, trial: Trial) -> ReplanningRounds:
        return ReplanningRounds(self, trial, Vocabulary.from_problem(trial.episode.problem))


def IterativeReplanningPlanner(
    backend: LLMBackend, settings: RunSettings | None = None, progress: Progress | None = None
) -> OnlinePlanner:
    """One task plan per query, re-asked with failure feedback, one step after 5 failures.

    ``settings`` is the run's settings tree (None: :class:`RunSettings`' defaults, which
    ``stalm solve --planner iterative-replanning`` runs): the prompt options (whose occlusion
    predicates the trial computes), whether replies are constrained (``llm.constrained``,
    None: for the embedded model only) and the sampling come from it."""
    run_settings = settings or RunSettings()
    options = run_settings.prompt
    method = Replanning(backend, use_constraint(run_settings, backend), options)
    occlusion = options.occlusion_predicates
    return OnlinePlanner(
        "iterative-replanning", run_settings, method, progress, occlusion=occlusion
    )


@dataclass
class ReplanningRounds:
    """One trial's rounds: up to ``attempts_per_state`` queries at a state, then a step."""

    planner: Replanning
    trial: Trial
    vocabulary: Vocabulary
    memory: list[FailedPlan] = field(default_factory=list)
    """Failed plans tried from the current state (cleared when an action is executed)."""
    memory_at: int = 0
    """How many actions had been executed when ``memory`` was written."""
    queries: int = 0
    feedback_queries: int = 0
    forced_steps: int = 0
    rounds: int = 0

    def decide(self) -> Decision:
        trial, constants = self.trial, self.planner.constants
        episode, problem, done = trial.episode, trial.episode.problem, trial.done
        if done != self.memory_at:
            self.memory, self.memory_at = [], done
        trial.say(f"step {done}: predicates")
        predicates = episode.predicates()
        base_prompt = problem_prompt(problem, predicates.literals, self.planner.options)
        latest: ConcretePlan | None = None
        to_execute: tuple[Action, ...] = ()
        for attempt in range(constants.attempts_per_state):
            if episode.out_of_time():
                break
            recent = self.memory[-constants.max_failed_plans :]
            trial.say(f"step {done}: query {attempt + 1} ({len(recent)} failed plan(s) shown)")
            proposal = ask_for_task_plans(
                self.planner.backend,
                self.vocabulary,
                with_feedback(base_prompt, recent),
                1,
                query_seed(trial.seed, self.rounds, attempt),
                constrained=self.planner.constrained,
                temperature=constants.temperature,
                deadline=episode.deadline,
            )
            episode.record_query(proposal)
            self.queries += 1
            self.feedback_queries += bool(recent)
            trial.replans = self.feedback_queries
            reason = proposal.unparseable[0] if proposal.unparseable else "no reply"
            task_plan = (
                TaskPlan(proposal.plans[0]) if proposal.plans else TaskPlan.unreadable(reason)
            )
            with trial.phase("concretize"):
                concrete = concretize(
                    trial.domain,
                    episode.state,
                    [task_plan],
                    trial.rng,
                    depth0=done,
                    horizon=problem.horizon,
                )
            episode.count_failures(concrete)
            if concrete.success and concrete.solution is not None:
                to_execute = concrete.solution
                break
            latest = concrete.plans[0]
            self.memory.append(failed_plan(latest))
            self.memory = self.memory[-constants.max_failed_plans :]
        else:
            # five failures: the next action of the most recent plan, if it was feasible
            to_execute = latest.actions[:1] if latest is not None else ()
            self.forced_steps += bool(to_execute)
        self.rounds += 1
        return to_execute

    def details(self) -> ReplanningDetails:
        backend = self.planner.backend
        return ReplanningDetails(
            f"{backend.name}:{backend.model}",
            self.queries,
            self.feedback_queries,
            self.rounds,
            self.forced_steps,
        )
