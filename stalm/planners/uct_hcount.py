"""UCT-with-Hcount (§4.2, Appendix C): UCT whose leaf value is the Hcount heuristic.

The same online search as :mod:`stalm.planners.uct`, with :class:`~stalm.search.hcount.
HcountLeafValue` in place of a random rollout. Hcount reads the occlusion predicates of every
leaf, so this planner always computes them, from the trial's one predicate memo (each leaf
brought forward from its parent).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from stalm.planners.tree_step import SearchStep, StalmSettings
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
        return replace(plain, value=HcountLeafValue(trial.problem, trial.memo))

    def start(self, trial: Trial) -> SearchStep:
        return HcountStep(trial, self.settings, self.policies(trial))


class HcountStep(SearchStep):
    """UCT's step, whose record also says how the leaves' predicates were made."""

    def __init__(self, trial: Trial, settings: StalmSettings, policies: SearchPolicies) -> None:
        super().__init__(trial, settings, policies)
        assert isinstance(policies.value, HcountLeafValue)
        self.leaf_value: HcountLeafValue = policies.value

    def details(self) -> dict[str, Any]:
        return {
            **super().details(),
            "hcount_leaves": {
                "predicates_from_scratch": self.leaf_value.computed_from_scratch,
                "predicates_brought_forward": self.leaf_value.brought_forward,
            },
        }


def build_uct_hcount(settings: RunSettings, progress: Progress | None) -> UctHcountPlanner:
    """The registry's builder."""
    return UctHcountPlanner(settings, progress)
