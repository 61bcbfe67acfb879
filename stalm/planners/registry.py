"""Every planner by name, built from one settings tree.

``stalm solve --planner NAME``, ``stalm rerun`` and ``stalm experiment`` all go through
:func:`build_planner`, so a planner is configured the same way wherever it runs, from a
:class:`~stalm.settings.tree.RunSettings`. The registry sits above the planner modules; it
pairs each row of :mod:`stalm.planners.registry_rows` (name, description, N_budget) with a
branch of :func:`_build`, which imports the planner's module when it runs, so listing the planners
(``stalm planners``, ``--help``) or resolving settings loads none of them. What the planners
share with it lives below both: the rows, :mod:`stalm.settings.tree` and
:mod:`stalm.proposers.model_backend`.
"""

from __future__ import annotations

import os
from dataclasses import replace

from stalm.errors import StalmError
from stalm.planners.registry_rows import PlannerRow, planner_rows
from stalm.progress import Progress
from stalm.proposers.model_backend import llm_backend
from stalm.settings.tree import RunSettings
from stalm.trial.result import Planner
from stalm.world.problem import Problem

PROPOSING = ("stalm", "stalm-no-uct")
"""The planners whose task plans come from ``proposer.kind`` (the other model-based
baselines ask the model with prompts of their own)."""


def _build(name: str, settings: RunSettings, progress: Progress | None) -> Planner:
    """Planner ``name`` (a row's) from ``settings``, importing its module only now (see the
    module docstring); the modules import nothing back from here."""
    if name in PROPOSING:
        from stalm.planners.stalm import StalmPlanner, best_prefix_first_action, proposer_for

        if name == "stalm":
            return StalmPlanner(proposer_for(settings), settings, progress)
        # the ablation is its own row (not a flag of STaLM's settings), so a planner's name is
        # what it is: STaLM's step whose no-goal-plan part is the best plan's first action
        return StalmPlanner(
            proposer_for(settings),
            settings,
            progress,
            name=name,
            no_goal_plan=best_prefix_first_action,
        )
    if name in ("uct", "uct-hcount"):
        from stalm.planners.uct import uct_planner

        return uct_planner(settings, progress, hcount=name == "uct-hcount")
    if name == "ep-saycan":
        from stalm.planners.saycan import EpSayCanPlanner

        return EpSayCanPlanner(llm_backend(settings), settings, progress)
    if name == "iterative-replanning":
        from stalm.planners.iterative_replanning import IterativeReplanningPlanner

        return IterativeReplanningPlanner(llm_backend(settings), settings, progress)
    if name == "llm-mcts":
        from stalm.planners.llm_mcts import LlmMctsPlanner
        from stalm.proposers.language_model import model_proposer

        return LlmMctsPlanner(model_proposer(settings), settings, progress)
    assert name == "pddlstream-adaptive", name  # every row of registry_rows.ROWS has its planner
    from stalm.planners.pddlstream import PDDLStreamPlanner

    return PDDLStreamPlanner(settings, progress)


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
    name: str, config: RunSettings | None = None, progress: Progress | None = None
) -> Planner:
    """The planner ``name`` configured by ``config`` (defaults: the paper's settings)."""
    entry = planner_entry(name)
    return _build(name, entry.settings_for(config or RunSettings()), progress)
