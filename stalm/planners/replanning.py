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

import time
from dataclasses import dataclass, field

import numpy as np

from stalm.domain.mdp import Domain
from stalm.domain.outcome import Infeasibility
from stalm.domain.params import Action
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.backends.base import LLMBackend
from stalm.llm.feedback_prompt import MAX_FAILED_PLANS, FailedPlan, with_feedback
from stalm.llm.problem_prompt import problem_prompt
from stalm.llm.prompt import PromptOptions
from stalm.planners.base import PlanResult
from stalm.planners.episode import Episode, run_episode
from stalm.planners.plan_queries import query_seed
from stalm.planners.proposers import ask_for_task_plans
from stalm.planners.registry import PlannerConfig, Progress, llm_backend, use_constraint
from stalm.predicates.engine import PredicateEngine
from stalm.search import TaskPlan, concretize
from stalm.search.concretize import ConcretePlan
from stalm.world.problem import Problem


@dataclass(frozen=True)
class ReplanningSettings:
    """The paper's setting: 5 single-plan queries per state, 2 failed plans in the prompt."""

    attempts_per_state: int = 5
    max_failed_plans: int = MAX_FAILED_PLANS
    temperature: float = 1.0


def failed_plan(plan: ConcretePlan) -> FailedPlan:
    """The feedback record of a task plan Concretize could not take to the goal."""
    kind = plan.failure or "partially_achieved_goal"
    reason = plan.detail or "the goal does not hold"
    if plan.failed_step is not None:
        step = plan.steps[plan.failed_step]
        why = step.kappa if isinstance(step.kappa, Infeasibility) else step.outcome.failure
        if why is not None:
            reason = why.detail if why.kind == "precondition" else str(why)
    return FailedPlan(plan.task_plan.actions, kind, reason, plan.failed_step)


@dataclass
class IterativeReplanningPlanner:
    """One task plan per query, re-asked with failure feedback, one step after 5 failures."""

    backend: LLMBackend
    constrained: bool = False
    options: PromptOptions = field(default_factory=PromptOptions)
    settings: ReplanningSettings = field(default_factory=ReplanningSettings)
    progress: Progress | None = None

    @property
    def name(self) -> str:
        return "iterative-replanning"

    def _say(self, message: str) -> None:
        if self.progress is not None:
            self.progress(message)

    def solve(self, problem: Problem, seed: int, time_budget_s: float | None = None) -> PlanResult:
        return run_episode(problem, time_budget_s, lambda d, e: self._run(d, e, seed))

    def _run(self, domain: Domain, episode: Episode, seed: int) -> PlanResult:
        problem = episode.problem
        engine = PredicateEngine(
            problem, domain.sim, domain.base_planner, occlusion=self.options.occlusion_predicates
        )
        vocabulary = Vocabulary.from_problem(problem)
        rng = np.random.default_rng(seed)
        memory: list[FailedPlan] = []
        queries = feedback_queries = forced_steps = rounds = 0
        while True:
            termination = episode.stop_reason(domain)
            if termination is not None:
                break
            done = len(episode.executed)
            self._say(f"step {done}: predicates")
            predicates = episode.predicates(engine)
            base_prompt = problem_prompt(problem, predicates.literals, self.options)
            latest: ConcretePlan | None = None
            to_execute: tuple[Action, ...] = ()
            for attempt in range(self.settings.attempts_per_state):
                if episode.out_of_time():
                    break
                recent = memory[-self.settings.max_failed_plans :]
                self._say(f"step {done}: query {attempt + 1} ({len(recent)} failed plan(s) shown)")
                proposal = ask_for_task_plans(
                    self.backend,
                    vocabulary,
                    with_feedback(base_prompt, recent),
                    1,
                    query_seed(seed, rounds, attempt),
                    constrained=self.constrained,
                    temperature=self.settings.temperature,
                    deadline=episode.deadline,
                )
                episode.record_query(proposal)
                queries += 1
                feedback_queries += bool(recent)
                task_plan = (
                    TaskPlan(proposal.plans[0])
                    if proposal.plans
                    else TaskPlan.unreadable(
                        proposal.unparseable[0] if proposal.unparseable else "no reply"
                    )
                )
                tick = time.monotonic()
                concrete = concretize(
                    domain,
                    episode.state,
                    [task_plan],
                    rng,
                    depth0=done,
                    horizon=problem.horizon,
                )
                episode.clock.concretize += time.monotonic() - tick
                episode.count_failures(concrete)
                if concrete.success and concrete.solution is not None:
                    to_execute = concrete.solution
                    break
                latest = concrete.plans[0]
                memory.append(failed_plan(latest))
                memory = memory[-self.settings.max_failed_plans :]
            else:
                # five failures: the next action of the most recent plan, if it was feasible
                to_execute = latest.actions[:1] if latest is not None else ()
                forced_steps += bool(to_execute)
            rounds += 1
            if not to_execute:
                continue
            for action in to_execute:
                episode.execute(domain, action)
                self._say(f"executed {action.discrete}")
            memory = []
        return episode.finish(
            domain,
            self.name,
            seed,
            termination,
            replans=feedback_queries,
            details={
                "backend": f"{self.backend.name}:{self.backend.model}",
                "queries": queries,
                "queries_with_feedback": feedback_queries,
                "rounds": rounds,
                "forced_steps": forced_steps,
            },
        )


def build_iterative_replanning(
    config: PlannerConfig, progress: Progress | None
) -> IterativeReplanningPlanner:
    """The registry's builder: the configured (cached) backend and prompt options."""
    backend = llm_backend(config)
    return IterativeReplanningPlanner(
        backend,
        constrained=use_constraint(config, backend),
        options=config.prompt,
        progress=progress,
    )
