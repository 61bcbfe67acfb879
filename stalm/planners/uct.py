"""UCT and UCT-with-Hcount (§4.2, Appendix C): STaLM's online hybrid search with no task plans.

Each real step runs UCT over κ with progressive widening from the current state (Algorithms
3–5 with an empty warm start), N_budget = 35 simulations, and executes the tree's goal plan or
the root action the execution rule picks (:class:`~stalm.planners.tree_step.SearchStep`, the
step STaLM runs after Concretize). No language model. Plain UCT values a new leaf by a random
rollout and computes no predicates; UCT-with-Hcount values it by Appendix C's Hcount
(:class:`~stalm.search.hcount.HcountLeafValue`), which reads the occlusion predicates of every
leaf, so that planner always computes them, from the trial's one predicate memo (each leaf
brought forward from its parent).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from stalm.planners.registry_rows import planner_rows
from stalm.planners.tree_step import SearchStep, tree_planner
from stalm.progress import Progress
from stalm.search import SearchPolicies
from stalm.search.hcount import HcountLeafValue
from stalm.settings.tree import RunSettings
from stalm.trial.online import OnlinePlanner, Trial


@dataclass(frozen=True)
class UctSteps:
    """UCT's part of a planner: the run's settings tree (N_budget filled by its row) and its
    leaf value (a random rollout, or Hcount); called at a trial's start, its steps."""

    settings: RunSettings
    hcount: bool = False

    def __call__(self, trial: Trial) -> SearchStep:
        policies = SearchPolicies.from_settings(self.settings.search.search_settings())
        if not self.hcount:
            return SearchStep(trial, self.settings, policies)
        leaves = HcountLeafValue(trial.episode.problem, trial.memo)
        return SearchStep(trial, self.settings, replace(policies, value=leaves), leaves)


def uct_planner(settings: RunSettings, progress: Progress | None, *, hcount: bool) -> OnlinePlanner:
    """UCT run online (the 'uct' row; with ``hcount``, the 'uct-hcount' row) configured by a
    run's settings tree; of it, the proposer's part (N_batch, feedback, κ tries, backtracks)
    does not apply."""
    name = "uct-hcount" if hcount else "uct"
    settings = planner_rows()[name].settings_for(settings)
    return tree_planner(name, settings, UctSteps(settings, hcount), progress, leaf_occlusion=hcount)
