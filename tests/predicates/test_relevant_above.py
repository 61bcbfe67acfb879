"""Past ``predicates.relevant_above`` movable objects the predicates are relevant-only on
their own: the paper's sweep of every object outruns a budget on a large scene while a plan
touches a handful, and a user should not have to know the setting for ``stalm solve`` to
work. P1-P6 keep the paper's predicates."""

from __future__ import annotations

import json

import pytest

from stalm.errors import StalmError
from stalm.predicates.samples import PredicateSettings
from stalm.settings.io import with_values
from stalm.settings.tree import RunSettings
from stalm.world.problem import load_problem, shipped_problems_dir
from tests.cli_runner import run_cli

CLUTTER = str(shipped_problems_dir() / "layouts" / "clutter35.yaml")
"""A shipped layout of 35 objects."""


def test_above_the_threshold_the_predicates_turn_relevant_only() -> None:
    settings = PredicateSettings()
    assert settings.relevant_above == 64
    assert settings.for_objects(64) is settings
    assert settings.for_objects(65).relevant_only
    never = PredicateSettings(relevant_above=None)
    assert not never.for_objects(10_000).relevant_only
    chosen = PredicateSettings(relevant_only=True)
    assert chosen.for_objects(3) is chosen


@pytest.mark.parametrize("value", [-1, True, 1.5, "many"])
def test_a_threshold_that_is_no_count_is_refused(value) -> None:
    with pytest.raises(StalmError, match=r"predicates\.relevant_above must be a whole number"):
        PredicateSettings(relevant_above=value)


def test_the_resolved_settings_say_it_and_p1_to_p6_keep_the_papers() -> None:
    clutter = load_problem(CLUTTER)
    low = with_values(RunSettings(), [("predicates.relevant_above", 30)], "test")
    assert low.resolved(clutter).predicates.relevant_only
    assert not RunSettings().resolved(clutter).predicates.relevant_only
    for name in ("P1", "P2", "P3", "P4", "P5", "P6"):
        resolved = RunSettings().resolved(load_problem(name))
        assert not resolved.predicates.relevant_only, name
    off = with_values(RunSettings(), [("predicates.relevant_above", None)], "test")
    assert not off.resolved(clutter).predicates.relevant_only


def test_a_solve_says_so_in_one_line_and_records_it(monkeypatch, capsys, tmp_path) -> None:
    out = tmp_path / "result.json"
    code = run_cli(
        monkeypatch,
        "solve",
        CLUTTER,
        "--set",
        "predicates.relevant_above=30",
        "--time-budget",
        "0.5",
        "--json",
        str(out),
    )
    assert code in (0, 1)  # solved or out of time: either way the note and the record
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if "predicates.relevant_above" in line]
    assert len(notes) == 1, err
    assert notes[0].startswith("note: 35 objects, more than predicates.relevant_above (30)")
    record = json.loads(out.read_text())
    assert record["settings"]["predicates"]["relevant_only"] is True
    assert record["settings"]["predicates"]["relevant_above"] == 30
