"""One source of truth for a run's settings: every default lives in the settings tree
(:class:`RunSettings` and the layer dataclasses it composes), the methods' settings are views
built from it, and a planner built by hand runs what ``stalm solve`` runs."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from stalm.planners.iterative_replanning import (
    IterativeReplanningPlanner,
    Replanning,
    ReplanningConstants,
)
from stalm.planners.llm_mcts import LlmMctsPlanner
from stalm.planners.pddlstream import AdaptiveSettings
from stalm.planners.registry import build_planner, planners, resolve
from stalm.planners.registry_rows import planner_rows
from stalm.planners.saycan import EpSayCanPlanner, SayCan, SayCanConstants
from stalm.planners.stalm import StalmPlanner, StalmSteps, proposer_kind
from stalm.planners.uct import UctSteps, uct_planner
from stalm.proposers.fast_downward import SymbolicProposer
from stalm.proposers.language_model import LLMProposer
from stalm.proposers.noisy import NoisyProposer
from stalm.search import SearchSettings
from stalm.settings.io import setting_keys, with_values
from stalm.settings.tree import LlmSection, RunSettings, SearchSection, with_budget
from stalm.trial.online import OnlinePlanner
from tests.golden import assert_matches, plain
from tests.planners.llm_reply_doubles import ScriptedReplyBackendDouble

STALM = Path(__file__).resolve().parents[2] / "stalm"

METHOD_CONSTANTS: dict[type, set[str]] = {
    SayCanConstants: {"uniform_weight", "max_queries_per_step", "temperature"},
    ReplanningConstants: {"attempts_per_state", "max_failed_plans", "temperature"},
    AdaptiveSettings: {"initial_complexity", "search", "memory_limit_mb"},
}
"""Per method settings dataclass: the fields that keep a default of their own, each a
constant of the method that the settings tree does not hold."""


def _has_default(f: dataclasses.Field) -> bool:  # type: ignore[type-arg]
    return f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING


@pytest.mark.parametrize("view", list(METHOD_CONSTANTS), ids=lambda v: v.__name__)
def test_a_method_settings_class_has_defaults_only_for_constants_the_tree_does_not_hold(
    view: type,
) -> None:
    defaulted = {f.name for f in dataclasses.fields(view) if _has_default(f)}
    assert defaulted == METHOD_CONSTANTS[view]
    tree_leaves = {key.rsplit(".", 1)[1] for key in setting_keys()}
    # a constant of the method's own is no tree key under another section's name either
    # ('search' of AdaptiveSettings is Fast Downward's search, a string the tree has not)
    held = {"uniform_weight", "max_queries_per_step", "attempts_per_state", "max_failed_plans"}
    assert not (held & tree_leaves)


def test_the_search_section_takes_the_search_layers_defaults() -> None:
    assert SearchSection().search_settings(SearchSettings().budget) == SearchSettings()


def test_the_execution_rule_is_defined_and_checked_once() -> None:
    sources = {p: p.read_text(encoding="utf-8") for p in STALM.rglob("*.py")}
    defined = [p for p, text in sources.items() if re.search(r"^ExecutionRule = ", text, re.M)]
    assert [p.relative_to(STALM).as_posix() for p in defined] == ["settings/tree.py"]
    checked = [p for p, text in sources.items() if "unknown execution rule" in text]
    assert [p.relative_to(STALM).as_posix() for p in checked] == ["settings/tree.py"]


def test_the_proposer_kind_is_read_from_the_proposer() -> None:
    symbolic = SymbolicProposer()
    assert proposer_kind(symbolic) == "symbolic"
    assert proposer_kind(NoisyProposer(symbolic, 0.5)) == "noisy"
    assert proposer_kind(LLMProposer(ScriptedReplyBackendDouble(queue=[]))) == "llm"


def _tree(*values: tuple[str, object]) -> RunSettings:
    return with_values(RunSettings(), values, "test settings")


@pytest.mark.parametrize("kind", ["symbolic", "noisy", "llm"])
def test_stalm_built_by_hand_reads_what_the_registry_builds_for_its_proposer(kind) -> None:
    """Feedback and backtracks follow the proposer's kind as ``--proposer KIND`` has them;
    an explicit setting is kept."""
    tree = _tree(("proposer.kind", kind), ("llm.backend", "http://127.0.0.1:9/v1#m"))
    built = build_planner("stalm", tree)
    assert isinstance(built.start, StalmSteps)
    by_hand = StalmPlanner(built.start.proposer)
    assert isinstance(by_hand.start, StalmSteps)
    assert _method_reads(by_hand) == _method_reads(built)
    assert _trial_shape(by_hand) == _trial_shape(built)
    assert by_hand.start.settings.feedback() is (kind == "symbolic")
    off = StalmPlanner(built.start.proposer, _tree(("execution.feedback", False)))
    assert isinstance(off.start, StalmSteps)
    assert (off.start.settings.feedback(), off.start.settings.backtracks()) == (False, 0)


def _trial_shape(planner: OnlinePlanner) -> tuple[object, ...]:
    """What the online loop sets up for ``planner``'s trials."""
    settings = planner.settings
    return (
        planner.name,
        settings.samplers,
        settings.predicates,
        settings.rewards,
        planner.occlusion,
        settings.execution.reuse_tree,
    )


def _method_reads(planner: OnlinePlanner) -> object:
    """What ``planner``'s part holds of its settings: its constants (EP-SayCan and
    Iterative-Replanning), else its settings tree but for the language model (which the
    registry's planners here name and a planner built by hand is given)."""
    method = planner.start
    if isinstance(method, SayCan | Replanning):
        return method.constants
    return dataclasses.replace(method.settings, llm=LlmSection())  # type: ignore[attr-defined]


def test_the_other_planners_built_by_hand_read_what_the_registry_builds() -> None:
    tree = _tree(("llm.backend", "http://127.0.0.1:9/v1#m"))
    backend = ScriptedReplyBackendDouble(queue=[])
    by_hand = {
        "uct": uct_planner(RunSettings(), None, hcount=False),
        "uct-hcount": uct_planner(RunSettings(), None, hcount=True),
        "llm-mcts": LlmMctsPlanner(LLMProposer(backend)),
        "ep-saycan": EpSayCanPlanner(backend),
        "iterative-replanning": IterativeReplanningPlanner(backend),
    }
    for name, planner in by_hand.items():
        built = build_planner(name, tree)
        assert isinstance(built, OnlinePlanner), name
        assert type(planner.start) is type(built.start), name
        assert _method_reads(planner) == _method_reads(built), name
        assert _trial_shape(planner) == _trial_shape(built), name
    uct, hcount = by_hand["uct"].start, by_hand["uct-hcount"].start
    assert isinstance(uct, UctSteps) and isinstance(hcount, UctSteps)
    assert uct.settings.search.search_settings().budget == 35 and not uct.hcount and hcount.hcount
    assert by_hand["uct-hcount"].occlusion


def test_stalm_with_the_symbolic_proposer_and_no_settings_runs_what_stalm_solve_runs(
    problems,
) -> None:
    """``StalmPlanner(SymbolicProposer())`` executes the plan ``stalm solve P2 --proposer
    symbolic`` executes: the same actions, their continuous values within 1e-6."""
    problem = problems["P2"]
    by_hand = StalmPlanner(SymbolicProposer()).solve(problem, seed=0, time_budget_s=300)
    resolved = resolve("stalm", _tree(("proposer.kind", "symbolic")), problem)
    cli = build_planner("stalm", resolved).solve(
        with_budget(problem, resolved.budget), 0, resolved.budget.time_budget_s
    )
    assert by_hand.success and cli.success
    assert [a.discrete for a in by_hand.plan] == [a.discrete for a in cli.plan]
    assert_matches(plain(list(by_hand.plan)), plain(list(cli.plan)), tolerance=1e-6)


def test_each_planners_default_budget_is_its_registry_rows_and_the_settings_name_none() -> None:
    """N_budget when ``search.sims`` is None is a row of the registry (STaLM's 30, the
    baselines' 35), written there only, what the built planner searches with and what a
    record keeps; the settings code names no planner."""
    rows = {name: entry.sims for name, entry in planners().items()}
    assert rows == {
        "stalm": 30,
        "stalm-no-uct": 30,
        "uct": 35,
        "uct-hcount": 35,
        "ep-saycan": None,
        "iterative-replanning": None,
        "llm-mcts": 35,
        "pddlstream-adaptive": None,
    }
    tree = _tree(("llm.backend", "http://127.0.0.1:9/v1#m"))
    for name, sims in rows.items():
        assert resolve(name, tree).search.sims == sims, name
        if sims is not None:
            method = build_planner(name, tree).start
            assert method.settings.search.search_settings().budget == sims, name  # type: ignore[attr-defined]
    by_hand = StalmPlanner(SymbolicProposer()).start
    assert isinstance(by_hand, StalmSteps)
    assert by_hand.settings.search.search_settings().budget == rows["stalm"]
    settings_code = (STALM / "settings" / "tree.py").read_text(encoding="utf-8")
    assert not re.search(r'"(stalm|uct|uct-hcount|llm-mcts)"', settings_code)
    with pytest.raises(ValueError, match="runs no tree search"):
        planner_rows()["ep-saycan"].settings_for(tree).search.search_settings()
    # the rows are the one place N_budget is written: no planner module keeps a fallback
    for module in (STALM / "planners").glob("*.py"):
        code = module.read_text(encoding="utf-8")
        assert not re.search(r"^\w*BUDGET\w*\s*=", code, re.MULTILINE), module.name
