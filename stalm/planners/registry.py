"""Every planner by name, built from one plain configuration.

``stalm solve --planner NAME`` and ``stalm experiment`` both go through :func:`build_planner`,
so a planner is configured the same way wherever it runs. The registry sits above the planner
modules and imports each one; what they share with it (:class:`PlannerConfig`, the backend a
config names) lives below both, in :mod:`stalm.planners.config`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from stalm.domain.mdp import RewardSettings
from stalm.errors import StalmError
from stalm.planners.base import Planner
from stalm.planners.config import (
    SETTABLE,
    PlannerConfig,
    Progress,
    llm_backend,
    use_constraint,
    with_overrides,
)
from stalm.planners.iterative_replanning import build_iterative_replanning
from stalm.planners.llm_mcts import build_llm_mcts
from stalm.planners.pddlstream import build_pddlstream_adaptive
from stalm.planners.proposers import LLMProposer, TaskPlanProposer
from stalm.planners.saycan import build_ep_saycan
from stalm.planners.stalm import StalmPlanner
from stalm.planners.stalm_no_uct import StalmNoUctPlanner
from stalm.planners.symbolic import SymbolicProposer
from stalm.planners.tree_step import StalmSettings
from stalm.planners.uct import UCT_BUDGET, UctPlanner
from stalm.planners.uct_hcount import UctHcountPlanner
from stalm.search import SearchSettings

__all__ = [
    "SETTABLE",
    "PlannerConfig",
    "PlannerEntry",
    "Progress",
    "build_planner",
    "llm_backend",
    "planner_entry",
    "planners",
    "use_constraint",
    "with_overrides",
]

STALM_BUDGET = 30
"""N_budget of STaLM (Appendix B)."""

Builder = Callable[[PlannerConfig, Progress | None], Planner]


@dataclass(frozen=True)
class PlannerEntry:
    """One planner: its name, what it is, whether it needs a language model, how to build it."""

    name: str
    description: str
    uses_llm: bool
    build: Builder


def proposer_for(config: PlannerConfig) -> TaskPlanProposer:
    """STaLM's proposer: the symbolic planner, or the configured (cached) language model."""
    if config.proposer == "symbolic":
        return SymbolicProposer(goal_relations_only=config.goal_relations_only)
    backend = llm_backend(config)
    return LLMProposer(backend, config.prompt, constrained=use_constraint(config, backend))


def tree_settings(config: PlannerConfig, *, proposes: bool) -> StalmSettings:
    """The settings of the tree planners (STaLM's; UCT's when nothing ``proposes``)."""
    budget = config.sims if config.sims is not None else (STALM_BUDGET if proposes else UCT_BUDGET)
    feedback = config.feedback
    if feedback is None:
        feedback = config.proposer == "symbolic"
    return StalmSettings(
        n_batch=config.batch,
        search=SearchSettings(budget=budget),
        reuse_tree=config.reuse_tree,
        feedback=feedback and proposes,
        execution=config.execution,  # type: ignore[arg-type]
        kappa_tries=config.kappa_tries,
        backtracks=config.backtracks if config.backtracks is not None else (6 if feedback else 0),
        rewards=RewardSettings(goal_atom_lost=config.goal_atom_lost),
        # the symbolic proposer plans with occlusions whatever the prompt options say
        occlusion_predicates=(config.proposer == "symbolic" or config.prompt.occlusion_predicates),
    )


def build_stalm(config: PlannerConfig, progress: Progress | None) -> StalmPlanner:
    return StalmPlanner(proposer_for(config), tree_settings(config, proposes=True), progress)


def build_stalm_no_uct(config: PlannerConfig, progress: Progress | None) -> StalmNoUctPlanner:
    return StalmNoUctPlanner(proposer_for(config), tree_settings(config, proposes=True), progress)


def build_uct(config: PlannerConfig, progress: Progress | None) -> UctPlanner:
    return UctPlanner(tree_settings(config, proposes=False), progress)


def build_uct_hcount(config: PlannerConfig, progress: Progress | None) -> UctHcountPlanner:
    return UctHcountPlanner(tree_settings(config, proposes=False), progress)


_ENTRIES: tuple[PlannerEntry, ...] = (
    PlannerEntry(
        "stalm",
        "STaLM: task plans from the proposer, Concretize, warm-started hybrid UCT (N_budget 30)",
        True,
        build_stalm,
    ),
    PlannerEntry(
        "stalm-no-uct",
        "STaLM without UCT (Table 3): Concretize only, then the next action of the best plan",
        True,
        build_stalm_no_uct,
    ),
    PlannerEntry(
        "uct",
        "Hybrid UCT with random rollouts and no guidance (N_budget 35)",
        False,
        build_uct,
    ),
    PlannerEntry(
        "uct-hcount",
        "UCT whose leaf value is Appendix C's Hcount heuristic (N_budget 35)",
        False,
        build_uct_hcount,
    ),
    PlannerEntry(
        "ep-saycan",
        "SayCan with an empirical policy: 5 replies to a history-only prompt times precondition "
        "affordance, no search",
        True,
        build_ep_saycan,
    ),
    PlannerEntry(
        "iterative-replanning",
        "One plan per query; on failure re-ask with up to two failed plans and the failure "
        "(5 attempts, then one step)",
        True,
        build_iterative_replanning,
    ),
    PlannerEntry(
        "llm-mcts",
        "MCTS with PUCT whose prior is the first actions of 5 replies at every new node "
        "(N_budget 35)",
        True,
        build_llm_mcts,
    ),
    PlannerEntry(
        "pddlstream-adaptive",
        "PDDLStream's adaptive algorithm: Fast Downward over sampled values as PDDL objects, "
        "failed samples fed back",
        False,
        build_pddlstream_adaptive,
    ),
)


def planners() -> dict[str, PlannerEntry]:
    """Every planner by name, in the order the README's table lists them."""
    return {entry.name: entry for entry in _ENTRIES}


def planner_entry(name: str) -> PlannerEntry:
    known = planners()
    if name not in known:
        raise StalmError(f"unknown planner '{name}' (available: {', '.join(known)})")
    return known[name]


def build_planner(
    name: str, config: PlannerConfig | None = None, progress: Progress | None = None
) -> Planner:
    """The planner ``name`` configured by ``config`` (defaults: the paper's settings)."""
    return planner_entry(name).build(config or PlannerConfig(), progress)
