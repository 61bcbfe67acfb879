"""The settings tree: today's defaults, every section reaching the planners, dotted overrides
checked by key and type, files, and the resolved tree a record keeps."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from stalm.errors import StalmError
from stalm.planners.registry import build_planner, resolve
from stalm.search import SearchSettings
from stalm.settings.io import (
    changed,
    from_mapping,
    setting_keys,
    to_dict,
    to_yaml,
    with_file,
    with_overrides,
    with_values,
)
from stalm.settings.tree import FLAT_NAMES, RunSettings

MODEL = "http://127.0.0.1:9/v1#m"
"""A server nothing listens on: building a planner never contacts it."""


def test_the_flat_names_set_the_tree_paths_they_name() -> None:
    """The flat names (``--set sims=7``, settings files and records written before the tree)
    set exactly the tree's keys in :data:`FLAT_NAMES`, each value checked by the tree."""
    flat = {
        "llm": "ollama:m",
        "proposer": "symbolic",
        "sims": 7,
        "batch": 3,
        "feedback": False,
        "reuse_tree": False,
        "execution": "best_q",
        "kappa_tries": 1,
        "backtracks": 2,
        "goal_atom_lost": 0.0,
        "goal_relations_only": False,
        "cache_mode": "off",
    }
    by_flat = with_values(RunSettings(), list(flat.items()), "flat")
    by_path = with_values(
        RunSettings(), [(FLAT_NAMES[name], value) for name, value in flat.items()], "paths"
    )
    assert by_flat == by_path != RunSettings()
    assert changed(by_flat) == {FLAT_NAMES[name]: value for name, value in flat.items()}
    with pytest.raises(StalmError, match=r"search\.sims"):
        with_values(RunSettings(), [("sims", -1)], "flat")


def test_the_default_tree_builds_the_tree_planners_as_before() -> None:
    """What the tree planners' steps read of the default tree: the values the registry built
    from the flat defaults before the tree."""
    for planner, budget in (("stalm", 30), ("uct", 35)):
        read = build_planner(planner, RunSettings()).start.settings  # type: ignore[attr-defined]
        execution = read.execution
        assert read.search.search_settings() == SearchSettings(budget=budget)
        assert (read.search.batch, read.feedback(), read.backtracks()) == (5, False, 0)
        assert (execution.feedback_rounds, execution.search_rounds) == (8, 10)
        assert (execution.step_share, execution.rule, execution.kappa_tries) == (
            1.0,
            "progress",
            3,
        )
    symbolic = with_values(RunSettings(), [("proposer", "symbolic")], "test")
    assert (symbolic.feedback(), symbolic.backtracks()) == (True, 6)


# (dotted key, value, planner, what the built planner holds for it)
REACHES = [
    ("search.c", 20.0, "stalm", lambda p: p.start.settings.search.search_settings().c),
    ("search.k", 2.0, "uct", lambda p: p.start.settings.search.search_settings().k),
    ("search.alpha", 0.3, "uct-hcount", lambda p: p.start.settings.search.search_settings().alpha),
    ("search.gamma", 0.9, "llm-mcts", lambda p: p.start.settings.search.search_settings().gamma),
    (
        "search.horizon",
        12,
        "stalm-no-uct",
        lambda p: p.start.settings.search.search_settings().horizon,
    ),
    ("search.sims", 9, "llm-mcts", lambda p: p.start.settings.search.search_settings().budget),
    ("search.batch", 3, "ep-saycan", lambda p: p.start.settings.search.batch),
    ("rewards.goal", 50.0, "uct", lambda p: p.settings.rewards.goal),
    ("rewards.infeasible", -1.0, "llm-mcts", lambda p: p.settings.rewards.infeasible),
    ("samplers.pick_tries", 5, "stalm", lambda p: p.settings.samplers.pick_tries),
    ("samplers.place_tries", 6, "pddlstream-adaptive", lambda p: p.samplers.place_tries),
    (
        "predicates.pick_samples",
        4,
        "iterative-replanning",
        lambda p: p.settings.predicates.pick_samples,
    ),
    ("predicates.workers", 2, "stalm", lambda p: p.settings.predicates.workers),
    ("execution.kappa_tries", 2, "ep-saycan", lambda p: p.start.settings.execution.kappa_tries),
    ("execution.step_share", 0.5, "stalm", lambda p: p.start.settings.execution.step_share),
    ("execution.feedback_rounds", 3, "stalm", lambda p: p.start.settings.execution.feedback_rounds),
    ("execution.search_rounds", 4, "uct", lambda p: p.start.settings.execution.search_rounds),
    ("execution.reuse_tree", False, "llm-mcts", lambda p: p.settings.execution.reuse_tree),
    (
        "proposer.goal_relations_only",
        False,
        "stalm",
        lambda p: p.start.proposer.goal_relations_only,
    ),
    (
        "proposer.break_occlusion_cycles",
        False,
        "stalm",
        lambda p: p.start.proposer.break_occlusion_cycles,
    ),
    (
        "proposer.needed_objects_only",
        False,
        "stalm",
        lambda p: p.start.proposer.needed_objects_only,
    ),
    (
        "prompt.ask_challenges",
        False,
        "iterative-replanning",
        lambda p: p.start.options.ask_challenges,
    ),
]


@pytest.mark.parametrize(
    ("key", "value", "planner", "held"), REACHES, ids=[f"{r[2]}:{r[0]}" for r in REACHES]
)
def test_a_setting_set_by_its_dotted_key_reaches_the_planner(key, value, planner, held) -> None:
    base = ["llm.backend=" + MODEL]
    if key.startswith("proposer."):
        base.append("proposer.kind=symbolic")
    settings = with_overrides(RunSettings(), [*base, f"{key}={value}"])
    assert held(build_planner(planner, settings)) == value


def test_values_are_read_as_yaml_and_checked_against_the_field() -> None:
    settings = with_overrides(
        RunSettings(),
        [
            "search.c=30",  # an int for a float field
            "search.sims=null",
            "execution.feedback=yes",
            "samplers.pitch_range=[0.1, 0.5]",
            "llm.backend=http://host:8080/v1#model",
            "rewards.goal=1e2",
            "search.batch=5",
        ],
    )
    assert settings.search.c == 30.0 and isinstance(settings.search.c, float)
    assert settings.execution.feedback is True
    assert settings.samplers.pitch_range == (0.1, 0.5)
    assert settings.llm.backend == "http://host:8080/v1#model"
    assert settings.rewards.goal == 100.0  # PyYAML reads 1e2 as text: a float field takes it
    assert changed(settings) == {
        "search.c": 30.0,
        "execution.feedback": True,
        "samplers.pitch_range": [0.1, 0.5],
        "llm.backend": "http://host:8080/v1#model",
    }


def test_the_flat_names_of_before_the_tree_still_work() -> None:
    settings = with_overrides(
        RunSettings(), ["execution=best_q", "reuse_tree=false", "goal_atom_lost=0", "sims=4"]
    )
    assert settings.execution.rule == "best_q" and settings.execution.reuse_tree is False
    assert settings.rewards.goal_atom_lost == 0.0 and settings.search.sims == 4


@pytest.mark.parametrize(
    ("pair", "named", "listed"),
    [
        ("search.cc=1", "'search.cc'", "search.c, search.k"),
        ("serch.c=1", "'serch.c'", "budget, search, rewards"),
        ("search=1", "'search' is a section", "search.sims"),
        ("search.c=fast", "search.c must be a number, got 'fast'", None),
        ("search.sims=2.5", "search.sims must be an integer or null", None),
        ("execution.rule=greedy", "execution.rule must be one of progress, best_q", None),
        ("execution.reuse_tree=3", "execution.reuse_tree must be true or false", None),
        ("samplers.pitch_range=[1]", "samplers.pitch_range must be a list of 2 numbers", None),
        ("samplers.pick_tries=-1", "samplers.pick_tries must be an integer >= 0", None),
        ("search.gamma=2", "'gamma' must be in (0, 1]", None),
        ("execution.step_share=0", "execution.step_share must be in (0, 1]", None),
        ("execution.search_rounds=0", "execution.search_rounds must be an integer >= 1", None),
        ("budget.horizon=0", "budget.horizon must be an integer >= 1", None),
        ("proposer.kind=gpt", "proposer.kind must be one of llm, symbolic, noisy", None),
        ("proposer.noise=1", "'proposer.noise' is a section", "proposer.noise.rate"),
        ("proposer.noise.rte=1", "'proposer.noise.rte'", "proposer.noise.weights"),
        ("proposer.noise.rate.x=1", "proposer.noise.rate is a value", None),
        ("proposer.noise.rate=1.5", "proposer.noise.rate must be in [0, 1]", None),
        ("proposer.noise.rate=-0.1", "proposer.noise.rate must be in [0, 1]", None),
        ("proposer.noise.weights=[1, 1]", "proposer.noise.weights must be a list of 3", None),
        ("proposer.noise.weights=[0, 0, 0]", "proposer.noise.weights must be 3 numbers >= 0", None),
        ("proposer.noise.weights=[1, -1, 1]", "proposer.noise.weights must be 3 numbers", None),
        ("proposer.noise.inner=noisy", "proposer.noise.inner must be one of symbolic, llm", None),
        ("c", "expected KEY=VALUE", None),
    ],
)
def test_a_bad_key_or_value_is_one_line_naming_it(
    pair: str, named: str, listed: str | None
) -> None:
    with pytest.raises(StalmError) as caught:
        with_overrides(RunSettings(), [pair])
    message = str(caught.value)
    assert "\n" not in message and named in message, message
    assert message.startswith(f"--set {pair}"), message
    if listed is not None:
        assert listed in message, message


def test_a_file_then_overrides_build_the_tree(tmp_path: Path) -> None:
    run = tmp_path / "run.yaml"
    run.write_text("search:\n  c: 10\n  sims: 2\nexecution.rule: best_q\nbatch: 4\n")
    settings = with_overrides(with_file(RunSettings(), run), ["search.sims=6"])
    assert (settings.search.c, settings.search.sims, settings.search.batch) == (10.0, 6, 4)
    assert settings.execution.rule == "best_q"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"search": {"c": "x"}}))
    with pytest.raises(StalmError, match=r"bad\.json: search\.c must be a number"):
        with_file(RunSettings(), bad)
    bad.write_text(json.dumps({"serch": {"c": 1}}))
    with pytest.raises(StalmError, match=r"bad\.json: unknown setting 'serch'"):
        with_file(RunSettings(), bad)


def _dotted(data: dict, prefix: str = "") -> list[str]:
    """The dotted keys of the values of nested sections (``proposer.noise.rate``)."""
    keys: list[str] = []
    for name, value in data.items():
        keys += _dotted(value, f"{prefix}{name}.") if isinstance(value, dict) else [prefix + name]
    return keys


def test_the_yaml_of_a_tree_reads_back_as_the_same_tree() -> None:
    settings = with_overrides(
        RunSettings(),
        ["samplers.yaw_range=[-1, 1]", "search.c=7.5", "proposer.noise.weights=[1, 0, 2]"],
    )
    text = to_yaml(settings)
    assert "  noise:\n    rate: 0.5\n" in text  # a section inside a section
    assert from_mapping(yaml.safe_load(text), "yaml") == settings
    assert from_mapping(json.loads(json.dumps(to_dict(settings))), "json") == settings
    assert _dotted(to_dict(settings)) == setting_keys()
    assert "proposer.noise.rate" in setting_keys() and "proposer.noise" not in setting_keys()


def test_a_subsection_is_set_by_its_dotted_key_or_nested_in_a_file(tmp_path: Path) -> None:
    settings = with_overrides(RunSettings(), ["proposer.kind=noisy", "proposer.noise.rate=0.25"])
    assert (settings.proposer.kind, settings.proposer.noise.rate) == ("noisy", 0.25)
    assert changed(settings) == {"proposer.kind": "noisy", "proposer.noise.rate": 0.25}
    run = tmp_path / "run.yaml"
    run.write_text("proposer:\n  noise:\n    rate: 0.75\n    inner: llm\n")
    noise = with_file(RunSettings(), run).proposer.noise
    assert (noise.rate, noise.inner, noise.weights) == (0.75, "llm", (1.0, 1.0, 1.0))
    run.write_text("proposer:\n  kind:\n    rate: 1\n")
    with pytest.raises(StalmError, match=r"run\.yaml: proposer\.kind is a setting, not a section"):
        with_file(RunSettings(), run)


def test_resolving_decides_every_planner_choice_once(problems) -> None:
    p3 = problems["P3"]
    uct = resolve("uct", RunSettings(), p3)
    assert uct.search.sims == 35 and uct.budget.time_budget_s == p3.spec.time_budget_s
    assert uct.budget.horizon == p3.horizon
    assert (uct.execution.feedback, uct.execution.backtracks) == (False, 0)
    symbolic = resolve("stalm", with_overrides(RunSettings(), ["proposer.kind=symbolic"]))
    assert symbolic.search.sims == 30
    assert (symbolic.execution.feedback, symbolic.execution.backtracks) == (True, 6)
    assert symbolic.llm.backend is None, "no model asked: the llm section is left as it is"
    mcts = resolve("llm-mcts", with_overrides(RunSettings(), [f"llm.backend={MODEL}"]))
    assert (mcts.llm.backend, mcts.llm.constrained) == (MODEL, False)
    assert resolve("llm-mcts", mcts) == mcts and resolve("uct", uct, p3) == uct
    assert resolve("ep-saycan", RunSettings()).search.sims is None, "no search: no N_budget"
