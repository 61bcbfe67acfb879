"""UCT-with-Hcount (§4.2, Appendix C): UCT whose leaf value is the Hcount heuristic.

The same online search as :mod:`stalm.planners.uct`, with :class:`~stalm.search.hcount.
HcountLeafValue` in place of a random rollout. Hcount reads the occlusion predicates of every
leaf, so this planner always computes them, from the trial's one predicate memo (each leaf
brought forward from its parent).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, cast

from stalm.planners.tree_step import SearchStep
from stalm.planners.uct import UctPlanner
from stalm.progress import Progress
from stalm.search import SearchPolicies
from stalm.search.hcount import HcountLeafValue
from stalm.settings.tree import RunSettings
from stalm.trial.online import Trial


class UctHcountPlanner(UctPlanner):
    """UCT with Appendix C's Hcount as the leaf value (the 'uct-hcount' row); its settings
    always compute the occlusion predicates Hcount reads (:meth:`StalmSettings.of`)."""

    name = "uct-hcount"

    def policies(self, trial: Trial) -> SearchPolicies:
        plain = super().policies(trial)
        return replace(plain, value=HcountLeafValue(trial.episode.problem, trial.memo))

    def start(self, trial: Trial) -> SearchStep:
        policies = self.policies(trial)
        leaves = cast(HcountLeafValue, policies.value)
        return SearchStep(trial, self.settings, policies, lambda: hcount_details(leaves))


def hcount_details(leaves: HcountLeafValue) -> dict[str, Any]:
    """How the leaves' predicates were made, for the trial's details."""
    return {
        "hcount_leaves": {
            "predicates_from_scratch": leaves.computed_from_scratch,
            "predicates_brought_forward": leaves.brought_forward,
        }
    }


def build_uct_hcount(settings: RunSettings, progress: Progress | None) -> UctHcountPlanner:
    """The registry's builder."""
    return UctHcountPlanner(settings, progress)
