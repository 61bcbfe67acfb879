"""Every planner by name, built from one settings tree.

``stalm solve --planner NAME``, ``stalm rerun`` and ``stalm experiment`` all go through
:func:`build_planner`, so a planner is configured the same way wherever it runs, from a
:class:`~stalm.settings.tree.RunSettings`. The registry sits above the
planner modules; its table holds one small builder per planner that imports the planner's
module when it is called, so listing the planners (``stalm planners``, ``--help``) or
resolving settings loads none of them. What the planners share with it lives below both:
:mod:`stalm.settings.tree` and :mod:`stalm.proposers.model_backend`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, replace

from stalm.errors import StalmError
from stalm.progress import Progress
from stalm.settings.tree import RunSettings
from stalm.trial.result import Planner
from stalm.world.problem import Problem

__all__ = [
    "PROPOSING",
    "PlannerEntry",
    "build_planner",
    "planner_entry",
    "planners",
    "resolve",
]

Builder = Callable[[RunSettings, Progress | None], Planner]

PROPOSING = ("stalm", "stalm-no-uct")
"""The planners whose task plans come from ``proposer.kind`` (the other model-based
baselines ask the model with prompts of their own)."""


@dataclass(frozen=True)
class PlannerEntry:
    """One planner: its name, what it is, whether it needs a language model, how to build it."""

    name: str
    description: str
    uses_llm: bool
    build: Builder
    sims: int | None = None
    """N_budget when ``search.sims`` is None: STaLM's 30 (Appendix B), the baselines' 35
    (§4.2); None: the planner runs no tree search."""

    def settings_for(self, settings: RunSettings) -> RunSettings:
        """``settings`` as this row runs them: its N_budget where ``search.sims`` is None."""
        if self.sims is None or settings.search.sims is not None:
            return settings
        return replace(settings, search=replace(settings.search, sims=self.sims))


# Each builder imports its planner's module only when a planner is built (see the module
# docstring); the modules import nothing back from here.
def _stalm(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.stalm import StalmPlanner, proposer_for

    return StalmPlanner(proposer_for(settings), settings, progress)


def _stalm_no_uct(settings: RunSettings, progress: Progress | None) -> Planner:
    """STaLM's step whose no-goal-plan part is the best plan's first action: the ablation is
    its own row (not a flag of STaLM's settings), so a planner's name is what it is."""
    from stalm.planners.stalm import StalmPlanner, best_prefix_first_action, proposer_for

    return StalmPlanner(
        proposer_for(settings),
        settings,
        progress,
        name="stalm-no-uct",
        no_goal_plan=best_prefix_first_action,
    )


def _uct(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.uct import uct_planner

    return uct_planner("uct", settings, progress, hcount=False)


def _uct_hcount(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.uct import uct_planner

    return uct_planner("uct-hcount", settings, progress, hcount=True)


def _ep_saycan(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.saycan import build_ep_saycan

    return build_ep_saycan(settings, progress)


def _iterative_replanning(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.iterative_replanning import build_iterative_replanning

    return build_iterative_replanning(settings, progress)


def _llm_mcts(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.llm_mcts import build_llm_mcts

    return build_llm_mcts(settings, progress)


def _pddlstream_adaptive(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.pddlstream import build_pddlstream_adaptive

    return build_pddlstream_adaptive(settings, progress)


_ENTRIES: tuple[PlannerEntry, ...] = (
    PlannerEntry(
        "stalm",
        "STaLM: task plans from the proposer, Concretize, warm-started hybrid UCT (N_budget 30)",
        True,
        _stalm,
        sims=30,
    ),
    PlannerEntry(
        "stalm-no-uct",
        "STaLM without UCT (Table 3): Concretize only, then the next action of the best plan",
        True,
        _stalm_no_uct,
        sims=30,
    ),
    PlannerEntry(
        "uct",
        "Hybrid UCT with random rollouts and no guidance (N_budget 35)",
        False,
        _uct,
        sims=35,
    ),
    PlannerEntry(
        "uct-hcount",
        "UCT whose leaf value is Appendix C's Hcount heuristic (N_budget 35)",
        False,
        _uct_hcount,
        sims=35,
    ),
    PlannerEntry(
        "ep-saycan",
        "SayCan with an empirical policy: 5 replies to a history-only prompt times precondition "
        "affordance, no search",
        True,
        _ep_saycan,
    ),
    PlannerEntry(
        "iterative-replanning",
        "One plan per query; on failure re-ask with up to two failed plans and the failure "
        "(5 attempts, then one step)",
        True,
        _iterative_replanning,
    ),
    PlannerEntry(
        "llm-mcts",
        "MCTS with PUCT whose prior is the first actions of 5 replies at every new node "
        "(N_budget 35)",
        True,
        _llm_mcts,
        sims=35,
    ),
    PlannerEntry(
        "pddlstream-adaptive",
        "PDDLStream's adaptive algorithm: Fast Downward over sampled values as PDDL objects, "
        "failed samples fed back",
        False,
        _pddlstream_adaptive,
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


def asks_model(name: str, settings: RunSettings) -> bool:
    """Whether planner ``name`` asks a language model under ``settings`` (STaLM with the
    symbolic proposer, or the noisy one wrapping it, does not)."""
    modelless = not settings.proposer.asks_model() and name in PROPOSING
    return planner_entry(name).uses_llm and not modelless


def resolve(name: str, settings: RunSettings, problem: Problem | None = None) -> RunSettings:
    """``settings`` as planner ``name`` runs them (on ``problem``): every None decided
    (:meth:`RunSettings.resolved`), and for a planner that asks a model, the backend
    ($STALM_LLM when none is named) and whether its replies are constrained. This is what a
    record keeps, so the run can be repeated from it on another machine."""
    resolved = planner_entry(name).settings_for(settings).resolved(problem)
    llm = resolved.llm
    if not asks_model(name, resolved):
        return resolved
    from stalm.llm.backends import SPEC_ENV, make_backend
    from stalm.llm.backends.openai_compatible import BASE_URL_ENV

    # no model named: $STALM_LLM, else a server in $STALM_LLM_BASE_URL (left None), else
    # the embedded model, as make_backend decides
    default = None if os.environ.get(BASE_URL_ENV) else "embedded"
    backend = llm.backend or os.environ.get(SPEC_ENV) or default
    constrained = llm.constrained
    if constrained is None and llm.from_record:  # a record's backend is never built
        from stalm.llm.backends.identity import EMBEDDED_PROVIDER, spec_identity

        constrained = spec_identity(backend).provider == EMBEDDED_PROVIDER
    if constrained is None:
        constrained = make_backend(backend).name == "embedded"  # loads no model
    return replace(resolved, llm=replace(llm, backend=backend, constrained=constrained))


def build_planner(
    name: str,
    config: RunSettings | None = None,
    progress: Progress | None = None,
) -> Planner:
    """The planner ``name`` configured by ``config`` (defaults: the paper's settings)."""
    entry = planner_entry(name)
    return entry.build(entry.settings_for(config or RunSettings()), progress)
