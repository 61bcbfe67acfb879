"""STaLM (Algorithm 1), run online as the authors ran it.

Each real step: compute the state's predicates (Appendix A's cache after the first step), ask
the proposer for N_batch task plans, Concretize them (Algorithm 2); if one reaches the goal,
execute it; otherwise run WarmStartedUCT (Algorithms 3–5) warm-started with everything
Concretize explored; if a simulation reaches the goal, execute that plan, else execute the
root action with the highest Q and plan again from the resulting state. One wall-clock
deadline covers the whole trial and is honoured between simulations. The executed plan is
replayed in a fresh scene at the end; a plan that fails there is a failure, never a success.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from stalm.domain.mdp import Domain
from stalm.domain.params import Action
from stalm.planners.base import PlanResult
from stalm.planners.episode import Episode, run_episode
from stalm.planners.hcount import HcountLeafValue
from stalm.planners.proposers import TaskPlanProposer
from stalm.predicates.engine import PredicateEngine
from stalm.search import (
    SearchPolicies,
    SearchSettings,
    TaskPlan,
    concretize,
    warm_started_uct,
)
from stalm.world.problem import Problem

Progress = Callable[[str], None]


@dataclass(frozen=True)
class StalmSettings:
    """Appendix B: N_batch = 5, N_budget = 30, c = 50, PW (1.5, 0.15), γ = 0.99."""

    n_batch: int = 5
    search: SearchSettings = field(default_factory=SearchSettings)
    use_tree: bool = True
    """False gives 'STaLM w/o UCT' (Table 3): no simulations after Concretize."""
    leaf_value: str = "rollout"
    """'rollout' (STaLM, UCT) or 'hcount' (UCT-with-Hcount, Appendix C)."""
    occlusion_predicates: bool = True
    """Compute PickOccludedBy/PlaceOccludedBy for the prompt. False for Table 4's arms whose
    prompt does not show them, so those arms do not pay for motion planning they never use."""

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
        return run_episode(problem, time_budget_s, lambda d, e: self._run(d, e, seed))

    def _run(self, domain: Domain, episode: Episode, seed: int) -> PlanResult:
        problem = episode.problem
        engine = PredicateEngine(
            problem, domain.sim, domain.base_planner, occlusion=self.settings.needs_occlusion
        )
        rng = np.random.default_rng(seed)
        policies = self._policies(problem, engine)
        horizon = problem.horizon
        search = self.settings.search
        clock = episode.clock
        simulations = replans = 0
        step = 0
        while (termination := episode.stop_reason(domain)) is None:
            state = episode.state
            done = len(episode.executed)
            replans += 1
            task_plans: list[TaskPlan] = []
            if self.proposer is not None:
                self._say(f"step {done}: predicates")
                predicates = episode.predicates(engine)

                self._say(f"step {done}: asking {self.proposer.name} for task plans")
                proposal = self.proposer.propose(
                    problem,
                    state,
                    predicates.literals,
                    self.settings.n_batch,
                    seed * 1000 + step,
                    deadline=episode.deadline,
                )
                step += 1
                episode.record_query(proposal)
                if episode.out_of_time():
                    termination = "timeout"
                    break
                task_plans = [TaskPlan(plan) for plan in proposal.plans]
                task_plans += [TaskPlan.unreadable(reason) for reason in proposal.unparseable]

            tick = time.monotonic()
            self._say(f"step {done}: concretizing {len(task_plans)} task plans")
            concrete = concretize(domain, state, task_plans, rng, depth0=done, horizon=horizon)
            clock.concretize += time.monotonic() - tick
            episode.count_failures(concrete)

            to_execute: tuple[Action, ...] = ()
            if concrete.success and concrete.solution is not None:
                to_execute = concrete.solution
            elif self.settings.use_tree:
                tick = time.monotonic()
                self._say(f"step {done}: warm-started UCT, {search.budget} simulations")
                result = warm_started_uct(
                    domain,
                    state,
                    concrete.plans,
                    rng,
                    settings=search,
                    depth0=done,
                    deadline=episode.deadline,
                    policies=policies,
                )
                clock.tree += time.monotonic() - tick
                simulations += result.counters.simulations
                if result.goal_plan:
                    to_execute = result.goal_plan
                elif result.best_action is not None:
                    to_execute = (result.best_action,)
            else:
                to_execute = _first_action_of_best_prefix(concrete.plans)
            # nothing feasible found: ask again from the same state
            for action in to_execute:
                episode.execute(domain, action)
                self._say(f"executed {action.discrete}")

        details: dict[str, object] = {
            "proposer": self.proposer.name if self.proposer is not None else None
        }
        if isinstance(policies.value, HcountLeafValue):
            details["hcount_leaves"] = {
                "predicates_from_scratch": policies.value.computed_from_scratch,
                "predicates_brought_forward": policies.value.brought_forward,
            }
        return episode.finish(
            domain,
            self.name,
            seed,
            termination,
            simulations=simulations,
            replans=replans,
            details=details,
        )


def _first_action_of_best_prefix(plans: object) -> tuple[Action, ...]:
    """STaLM w/o UCT: the first action of the task plan that got furthest."""
    best: tuple[Action, ...] = ()
    for plan in plans:  # type: ignore[attr-defined]
        actions = plan.actions
        if len(actions) > len(best):
            best = actions
    return best[:1]
