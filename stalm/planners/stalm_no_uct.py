"""STaLM w/o UCT (Table 3): Concretize the proposer's task plans, and no search after it.

The ablation keeps STaLM's step -- predicates, N_batch task plans, Concretize, execute a plan
that reached the goal -- and replaces the warm-started search by the simplest use of what
Concretize found: the first action of the task plan that got furthest. It is its own class
(not a flag of STaLM's settings) so that a planner's name is what it is, never derived from
its settings.
"""

from __future__ import annotations

from stalm.domain.params import Action
from stalm.planners.stalm import NoGoalPlan, StalmPlanner, StalmStep, proposer_for
from stalm.progress import Progress
from stalm.search import ConcretePlan
from stalm.settings.tree import RunSettings
from stalm.trial.step_log import StepRecord


def best_prefix_first_action(
    step: StalmStep, plans: list[ConcretePlan], record: StepRecord
) -> tuple[Action, ...]:
    """STaLM w/o UCT's decision without a goal plan: the first action of the task plan that
    got furthest (the first of equally long ones)."""
    record.decision = "best_prefix"
    return max((plan.actions for plan in plans), key=len, default=())[:1]


class StalmNoUctPlanner(StalmPlanner):
    """STaLM without the tree search (Table 3's 'STaLM w/o UCT')."""

    name = "stalm-no-uct"

    def no_goal_plan(self) -> NoGoalPlan:
        return best_prefix_first_action


def build_stalm_no_uct(settings: RunSettings, progress: Progress | None) -> StalmNoUctPlanner:
    """The registry's builder."""
    return StalmNoUctPlanner(proposer_for(settings), settings, progress)
