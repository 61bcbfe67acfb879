"""Experiment plans: the paper's rows, shared seeds, scaled budgets, clear errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.experiments.suites import TABLE2_PLANNERS, build_plan, trial_specs
from stalm.experiments.trials import derive_seed
from stalm.settings.io import changed, with_overrides
from stalm.settings.tree import RunSettings


def test_table2_defaults_to_the_papers_seven_rows_on_six_problems() -> None:
    plan = build_plan("table2")
    assert tuple(arm.label for arm in plan.arms) == TABLE2_PLANNERS
    assert plan.problems == ("P1", "P2", "P3", "P4", "P5", "P6")
    assert plan.trials == 50


def test_every_planner_meets_the_same_seeds_and_budgets_are_scaled() -> None:
    plan = build_plan(
        "table2",
        planners=("uct", "stalm-symbolic"),
        problems=("P1", "P3"),
        trials=2,
        budget_scale=0.1,
        master_seed=4,
    )
    specs = trial_specs(plan)
    assert len(specs) == 2 * 2 * 2
    by = {(s.arm.label, s.problem, s.trial): s for s in specs}
    assert by[("uct", "P1", 1)].seed == by[("stalm-symbolic", "P1", 1)].seed
    assert by[("uct", "P1", 0)].seed != by[("uct", "P1", 1)].seed
    assert by[("uct", "P1", 0)].seed == derive_seed(4, "P1", 0) < 2**20
    assert by[("uct", "P1", 0)].time_budget_s == pytest.approx(30.0)
    assert by[("uct", "P3", 0)].time_budget_s == pytest.approx(60.0)
    assert by[("stalm-symbolic", "P1", 0)].arm.config.proposer.kind == "symbolic"
    assert len({s.key for s in specs}) == len(specs)
    # trial-major order: every (problem, planner) gets its first trial before any second
    assert [s.trial for s in specs[:4]] == [0, 0, 0, 0]


def test_table3_crosses_models_with_and_without_uct() -> None:
    plan = build_plan("table3", llms=("embedded", "ollama:llama3.1"))
    labels = [arm.label for arm in plan.arms]
    assert labels == [
        "stalm [embedded]",
        "stalm-no-uct [embedded]",
        "stalm [ollama:llama3.1]",
        "stalm-no-uct [ollama:llama3.1]",
    ]
    assert plan.arms[2].config.llm.backend == "ollama:llama3.1"


def test_table4_is_the_four_prompt_switch_combinations() -> None:
    plan = build_plan("table4")
    switches = {
        (a.config.prompt.occlusion_predicates, a.config.prompt.ask_challenges) for a in plan.arms
    }
    assert switches == {(True, True), (True, False), (False, True), (False, False)}
    assert {a.planner for a in plan.arms} == {"stalm"}


def test_table4_arms_compute_and_constrain_only_what_their_prompt_shows() -> None:
    from stalm.planners.registry import build_planner

    plan = build_plan("table4", llms=("http://127.0.0.1:9/v1#m",))
    for arm in plan.arms:
        planner = build_planner(arm.planner, arm.config)
        prompt = arm.config.prompt
        # the predicate engine plans occlusions only for a prompt that shows them
        assert planner.occlusion is prompt.occlusion_predicates, arm.label
        assert planner.start.proposer.options == prompt, arm.label
    hcount = build_planner("uct-hcount", plan.arms[-1].config)
    assert hcount.occlusion, "Hcount needs occlusions whatever the prompt"


def test_changing_the_budget_changes_the_trial_key_but_not_the_cache_mode() -> None:
    from dataclasses import replace

    [spec] = trial_specs(build_plan("figure5", problems=("P2",), trials=1))
    assert spec.key != replace(spec, time_budget_s=1.0).key
    settings = spec.arm.config
    other = replace(settings, llm=replace(settings.llm, cache="replay", cache_file="r.sqlite"))
    assert spec.key == replace(spec, arm=replace(spec.arm, config=other)).key


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"name": "table9"}, "unknown experiment 'table9'"),
        ({"name": "table2", "planners": ("uct", "nope")}, "unknown planner 'nope'"),
        ({"name": "table2", "planners": ("uct", "uct")}, "listed twice"),
        ({"name": "table2", "trials": 0}, "--trials"),
        ({"name": "table2", "budget_scale": 0.0}, "--budget-scale"),
    ],
)
def test_bad_choices_are_named(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(StalmError, match=message):
        build_plan(**kwargs)  # type: ignore[arg-type]


def test_an_unknown_problem_is_named() -> None:
    with pytest.raises(StalmError, match="P9"):
        trial_specs(build_plan("table2", problems=("P9",), planners=("uct",)))


# Keys computed before the settings tree existed (PlannerConfig, commit 9fe03af): the same
# trials must keep them, or a results log written then would not resume. The rows named after
# the paper's methods run the authors' settings since issue 26 (other trials, other keys).
KEYS_BEFORE_THE_SETTINGS_TREE = {
    ("table2", "stalm-symbolic", "P3"): "6f646db14a373d4f548d",
    ("table2", "stalm-feedback", "P1"): "3d7aa634d568e12de79b",
}


def test_trial_keys_of_default_settings_are_those_of_before_the_settings_tree() -> None:
    plan = build_plan(
        "table2", planners=("stalm-symbolic", "stalm-feedback"), problems=("P1", "P3"), trials=1
    )
    keys = {("table2", spec.arm.label, spec.problem): spec.key for spec in trial_specs(plan)}
    for cell, key in KEYS_BEFORE_THE_SETTINGS_TREE.items():
        assert keys[cell] == key, cell


def test_the_paper_rows_run_the_authors_settings_and_plus_rows_the_defaults() -> None:
    from stalm.experiments.suites import AUTHORS_SETTINGS, PAPER_ROWS, PLUS_ROWS
    from stalm.settings.io import changed

    rows = (*PAPER_ROWS, *(f"{name}+" for name in PLUS_ROWS))
    arms = {arm.label: arm for arm in build_plan("table2", planners=rows, trials=1).arms}
    for name in PAPER_ROWS:
        assert arms[name].planner == name
        config = arms[name].config
        for key, value in AUTHORS_SETTINGS.items():
            section, field = key.split(".")
            assert getattr(getattr(config, section), field) == value, (name, key)
    for name in PLUS_ROWS:
        assert arms[f"{name}+"].planner == name and changed(arms[f"{name}+"].config) == {}
    table3 = build_plan("table3", llms=("embedded",), trials=1).arms
    assert all(changed(arm.config)["execution.rule"] == "best_q" for arm in table3)


def test_the_issue13_results_logs_still_resume() -> None:
    """The commands written above docs/results.md's issue-13 tables (flat --set names
    included) find every trial of their results logs already done."""
    from stalm.settings.io import with_overrides
    from stalm.settings.tree import RunSettings

    folder = Path(__file__).resolve().parents[2] / "docs" / "results" / "issue13"
    everything_off = [
        "reuse_tree=false",
        "feedback=false",
        "execution=best_q",
        "goal_atom_lost=0",
        "kappa_tries=1",
        "goal_relations_only=false",
        "backtracks=0",
    ]
    runs = [
        ("after.jsonl", {"trials": 10}, []),
        (
            "without-reuse.jsonl",
            {"problems": ("P3", "P5", "P6"), "trials": 2},
            ["reuse_tree=false"],
        ),
        (
            "without-reward.jsonl",
            {"problems": ("P3", "P5", "P6"), "trials": 2},
            ["goal_atom_lost=0"],
        ),
        ("before.jsonl", {"problems": ("P3", "P5", "P6"), "trials": 2}, everything_off),
    ]
    unchanged = ("P1", "P2", "P3", "P4")  # P5 and P6 were rebuilt since (issue 26's grill trap)
    for name, options, overrides in runs:
        base = with_overrides(RunSettings(), overrides)
        problems = tuple(p for p in options.pop("problems", unchanged) if p in unchanged)
        plan = build_plan(
            "table2", planners=("stalm-symbolic",), base=base, problems=problems, **options
        )
        records = [json.loads(line) for line in (folder / name).read_text().splitlines()]
        logged = {r["key"] for r in records if r["problem"] in unchanged}
        assert {spec.key for spec in trial_specs(plan)} == logged, name


def test_a_setting_beyond_the_flat_ones_changes_the_key_and_an_arm_keeps_its_own() -> None:
    from stalm.settings.io import with_overrides
    from stalm.settings.tree import RunSettings

    def keys(*overrides: str) -> list[str]:
        base = with_overrides(RunSettings(), list(overrides))
        plan = build_plan("table2", planners=("uct",), problems=("P2",), trials=1, base=base)
        return [spec.key for spec in trial_specs(plan)]

    default = keys()
    assert keys("search.c=50") == default, "a value equal to the default is the default"
    assert keys("search.c=20") != default
    assert keys("samplers.pick_tries=3") != default
    assert keys("llm.cache=replay", "llm.cache_file=x.sqlite") == default
    assert keys("budget.time_budget_s=300") == keys() != keys("budget.time_budget_s=30")
    # the stalm-symbolic row stays symbolic whatever --set says
    base = with_overrides(RunSettings(), ["proposer.kind=llm"])
    [arm] = build_plan("table2", planners=("stalm-symbolic",), base=base).arms
    assert arm.config.proposer.kind == "symbolic"


def _noisy() -> RunSettings:
    return with_overrides(RunSettings(), ["proposer.kind=noisy"])


def test_table3_with_the_noisy_proposer_runs_both_rows_at_every_rate_and_uct_once() -> None:
    from stalm.experiments.suites import AUTHORS_SETTINGS

    rates = (0.0, 0.25, 0.5, 0.75, 1.0)
    plan = build_plan("table3", base=_noisy(), rates=rates, trials=5)
    labels = [arm.label for arm in plan.arms]
    assert labels == [
        *(f"stalm [noisy {r:g}]" for r in rates),
        *(f"stalm-no-uct [noisy {r:g}]" for r in rates),
        "uct",
    ]
    assert plan.problems == ("P1", "P2", "P3", "P4", "P5", "P6")
    for arm in plan.arms[:-1]:
        assert arm.config.proposer.kind == "noisy" and arm.planner in ("stalm", "stalm-no-uct")
        assert arm.config.proposer.noise.rate == float(arm.label.split()[-1].rstrip("]"))
        assert arm.config.execution.feedback is False  # the paper's rows: the authors' way
        assert arm.config.execution.rule == AUTHORS_SETTINGS["execution.rule"]
    uct = plan.arms[-1]
    assert uct.planner == "uct" and uct.config.proposer.kind == "llm"  # proposes nothing
    specs = trial_specs(plan)
    assert len(specs) == 11 * 6 * 5 and len({s.key for s in specs}) == len(specs)
    # every rate meets the same seeds
    seeds = {(s.problem, s.trial): s.seed for s in specs if s.arm.label == "stalm [noisy 0]"}
    assert all(seeds[(s.problem, s.trial)] == s.seed for s in specs)
    # one rate by default: proposer.noise.rate; the + rows on request
    plus = build_plan("table3", base=_noisy(), planners=("stalm+", "uct+"))
    assert [arm.label for arm in plus.arms] == ["stalm+ [noisy 0.5]", "uct+"]
    assert plus.arms[0].config.execution.rule == "progress"


def test_additions_leave_each_addition_out_alone_at_the_noisy_rate() -> None:
    plan = build_plan("additions", trials=5)
    assert plan.problems == ("P3", "P4", "P5", "P6")
    arms = {arm.label: arm for arm in plan.arms}
    base = arms["stalm+ [noisy 0.5]"].config
    assert base.proposer.kind == "noisy" and base.proposer.noise.rate == 0.5
    # STaLM as stalm-symbolic runs it (the tree's defaults), feedback off (the noisy default)
    assert (base.execution.rule, base.execution.reuse_tree, base.execution.kappa_tries) == (
        "progress",
        True,
        3,
    )
    assert base.rewards.goal_atom_lost == 3.0 and base.feedback() is False
    left_out = {
        label: changed(arm.config, base) for label, arm in arms.items() if arm.config != base
    }
    assert left_out == {
        "stalm+ [noisy 0.5] w/o tree reuse": {"execution.reuse_tree": False},
        "stalm+ [noisy 0.5] w/o progress rule": {"execution.rule": "best_q"},
        "stalm+ [noisy 0.5] w/o -3 for an undone conjunct": {"rewards.goal_atom_lost": 0.0},
        "stalm+ [noisy 0.5] w/o kappa retries": {"execution.kappa_tries": 1},
    }
    assert {arm.planner for arm in plan.arms} == {"stalm"}
    two = build_plan("additions", rates=(0.25, 0.5), problems=("P5",), trials=1)
    assert len(two.arms) == 10 and two.problems == ("P5",)


@pytest.mark.parametrize(
    ("rates", "noisy", "message"),
    [
        ((0.5,), False, "--rates goes with the noisy proposer"),
        ((0.5, 0.5), True, "lists a rate twice"),
        ((1.5,), True, r"must be in \[0, 1\], got 1.5"),
        ((float("nan"),), True, "must be in"),
    ],
)
def test_bad_rates_are_named(rates, noisy: bool, message: str) -> None:
    base = _noisy() if noisy else None
    with pytest.raises(StalmError, match=message):
        build_plan("table3", base=base, rates=rates)
