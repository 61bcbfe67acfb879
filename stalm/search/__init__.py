"""Concretize, the hybrid search tree, UCT with progressive widening and WarmUpTree (§3.3).

Tree mechanics (:mod:`~stalm.search.tree`) are separate from the choices made on it
(:mod:`~stalm.search.policies`), so baselines swap policies, not algorithms.
"""

from stalm.search.concretize import (
    ConcretePlan,
    ConcreteStep,
    ConcretizeResult,
    FailureKind,
    TaskPlan,
    concretize,
)
from stalm.search.policies import (
    LeafValue,
    ProgressiveWidening,
    RolloutValue,
    SearchPolicies,
    StateValue,
    UCTSelection,
    best_by_q,
    rollout,
)
from stalm.search.settings import SearchSettings
from stalm.search.tree import SearchTree
from stalm.search.uct import SearchCounters, SearchResult, simulate, warm_started_uct
from stalm.search.warmup import warm_up_tree

__all__ = [
    "ConcretePlan",
    "ConcreteStep",
    "ConcretizeResult",
    "FailureKind",
    "LeafValue",
    "ProgressiveWidening",
    "RolloutValue",
    "SearchCounters",
    "SearchPolicies",
    "SearchResult",
    "SearchSettings",
    "SearchTree",
    "StateValue",
    "TaskPlan",
    "UCTSelection",
    "best_by_q",
    "concretize",
    "rollout",
    "simulate",
    "warm_started_uct",
    "warm_up_tree",
]
