"""Every planner by name, built from one settings tree.

``stalm solve --planner NAME``, ``stalm rerun`` and ``stalm experiment`` all go through
:func:`build_planner`, so a planner is configured the same way wherever it runs, from a
:class:`~stalm.settings.tree.RunSettings`. The registry sits above the planner modules; it
pairs each row of :mod:`stalm.planners.registry_rows` (name, description, N_budget) with one
small builder that imports the planner's module when it is called, so listing the planners
(``stalm planners``, ``--help``) or resolving settings loads none of them. What the planners
share with it lives below both: the rows, :mod:`stalm.settings.tree` and
:mod:`stalm.proposers.model_backend`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import replace

from stalm.errors import StalmError
from stalm.planners.registry_rows import PlannerRow, planner_rows
from stalm.progress import Progress
from stalm.proposers.model_backend import llm_backend
from stalm.settings.tree import RunSettings
from stalm.trial.result import Planner
from stalm.world.problem import Problem

__all__ = [
    "PROPOSING",
    "PlannerRow",
    "build_planner",
    "planner_entry",
    "planners",
    "resolve",
]

Builder = Callable[[RunSettings, Progress | None], Planner]

PROPOSING = ("stalm", "stalm-no-uct")
"""The planners whose task plans come from ``proposer.kind`` (the other model-based
baselines ask the model with prompts of their own)."""


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
    from stalm.planners.saycan import EpSayCanPlanner

    return EpSayCanPlanner(llm_backend(settings), settings, progress)


def _iterative_replanning(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.iterative_replanning import IterativeReplanningPlanner

    return IterativeReplanningPlanner(llm_backend(settings), settings, progress)


def _llm_mcts(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.llm_mcts import LlmMctsPlanner
    from stalm.proposers.language_model import model_proposer

    return LlmMctsPlanner(model_proposer(settings), settings, progress)


def _pddlstream_adaptive(settings: RunSettings, progress: Progress | None) -> Planner:
    from stalm.planners.pddlstream import PDDLStreamPlanner

    return PDDLStreamPlanner(settings, progress)


_BUILDERS: dict[str, Builder] = {
    "stalm": _stalm,
    "stalm-no-uct": _stalm_no_uct,
    "uct": _uct,
    "uct-hcount": _uct_hcount,
    "ep-saycan": _ep_saycan,
    "iterative-replanning": _iterative_replanning,
    "llm-mcts": _llm_mcts,
    "pddlstream-adaptive": _pddlstream_adaptive,
}
"""Each row's builder (:data:`~stalm.planners.registry_rows.ROWS`), by planner name."""


def planners() -> dict[str, PlannerRow]:
    """Every planner by name, in the order the README's table lists them."""
    return planner_rows()


def planner_entry(name: str) -> PlannerRow:
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
    return _BUILDERS[name](entry.settings_for(config or RunSettings()), progress)
