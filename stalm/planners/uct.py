"""UCT (§4.2's baseline): STaLM's online hybrid search with no task plans to warm it.

Each real step runs UCT over κ with progressive widening and random rollouts from the current
state (Algorithms 3–5 with an empty warm start), N_budget = 35 simulations, and executes the
tree's goal plan or the root action the execution rule picks (:class:`~stalm.planners.
tree_step.SearchStep`, the step STaLM runs after Concretize). No language model, no
predicates.
"""

from __future__ import annotations

from stalm.planners.tree_step import SearchStep, StalmSettings, TreePlanner
from stalm.progress import Progress
from stalm.search import SearchPolicies
from stalm.settings.tree import RunSettings
from stalm.trial.online import Sampling, Trial


class UctPlanner(TreePlanner):
    """Plain hybrid UCT run online (the 'uct' row), configured by a run's settings tree
    (None: :class:`RunSettings`' defaults, which ``stalm solve --planner uct`` runs); of it,
    the proposer's part (N_batch, feedback, κ tries, backtracks) does not apply."""

    name = "uct"

    def __init__(
        self, settings: RunSettings | None = None, progress: Progress | None = None
    ) -> None:
        run_settings = settings or RunSettings()
        self.settings = StalmSettings.of(run_settings, self.name, proposes=False)
        self.sampling = Sampling.of(run_settings)
        self.progress = progress

    def policies(self, trial: Trial) -> SearchPolicies:
        """The search's policies: UCT's, with random rollouts at new leaves."""
        return SearchPolicies.from_settings(self.settings.search)

    def start(self, trial: Trial) -> SearchStep:
        return SearchStep(trial, self.settings, self.policies(trial))


def build_uct(settings: RunSettings, progress: Progress | None) -> UctPlanner:
    """The registry's builder."""
    return UctPlanner(settings, progress)
