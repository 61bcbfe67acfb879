"""Bad numbers and arguments are one error line, never a hang or a traceback (issue 30, items
9-11): settings files get the problem files' guards, the Python API checks what the CLI
checks, and sizes, depths and non-finite values that crashed deep inside are refused at the
door."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli

ALIAS_BOMB = "".join(
    f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]\n" for i in range(1, 12)
).replace("*l0", "0")
"""About 500 bytes standing for 9**11 values once its aliases are expanded."""


@pytest.mark.parametrize(
    ("content", "named"),
    [
        (ALIAS_BOMB, "more than"),
        ("search: &s {c: *s}\n", "more than"),
        ("search:\n  c: '" + "x" * 1_100_000 + "'\n", "too long"),
        ("search: [unclosed\n", "not valid YAML"),
        ("search:\n  c: [" + "1, " * 50 + "1]\n", "search.c"),
    ],
)
def test_hostile_settings_files_are_one_error_line(
    monkeypatch, capsys, tmp_path: Path, content: str, named: str
) -> None:
    path = tmp_path / "run.yaml"
    path.write_text(content)
    started = time.monotonic()
    code = run_cli(monkeypatch, "solve", "P2", "--settings", str(path), "--show-settings")
    err = capsys.readouterr().err
    assert code == 2, err
    line = one_error_line(err)
    assert str(path) in line and named in line
    assert len(line) < 400
    assert time.monotonic() - started < 10


def test_a_device_as_settings_file(monkeypatch, capsys) -> None:
    code = run_cli(monkeypatch, "solve", "P2", "--settings", "/dev/zero", "--show-settings")
    assert code == 2
    assert "/dev/zero" in one_error_line(capsys.readouterr().err)


# ---------------------------------------------------------------------------------------------
# item 10: the Python API checks what the CLI checks, with the same messages


def _cli_message(monkeypatch, capsys, option: str, value: str) -> str:
    code = run_cli(monkeypatch, "solve", "P2", "--planner", "uct", option, value)
    assert code == 2
    return one_error_line(capsys.readouterr().err).split(option, 1)[1]


@pytest.mark.parametrize("planner", ["uct", "stalm", "pddlstream-adaptive"])
@pytest.mark.parametrize(
    ("keyword", "value", "option", "text"),
    [
        ("time_budget_s", float("nan"), "--time-budget", "nan"),
        ("time_budget_s", float("inf"), "--time-budget", "inf"),
        ("time_budget_s", 0.0, "--time-budget", "0"),
        ("time_budget_s", -5.0, "--time-budget", "-5"),
        ("seed", -1, "--seed", "-1"),
    ],
)
def test_the_api_checks_seed_and_budget_as_the_cli_does(
    monkeypatch, capsys, problems, planner, keyword, value, option, text
) -> None:
    from stalm.api import PlannerConfig, StalmError, build_planner

    built = build_planner(planner, PlannerConfig(proposer="symbolic", sims=1))
    arguments = {"seed": 0, "time_budget_s": 5.0, keyword: value}
    started = time.monotonic()
    with pytest.raises(StalmError) as error:
        built.solve(problems["P2"], **arguments)
    assert time.monotonic() - started < 1.0  # refused before any set-up
    message = str(error.value)
    assert message.startswith(keyword)
    assert message.split(keyword, 1)[1] == _cli_message(monkeypatch, capsys, option, text)


@pytest.mark.parametrize("seed", [True, 1.5, "3"])
def test_the_api_refuses_seeds_that_are_not_integers(problems, seed) -> None:
    from stalm.api import PlannerConfig, StalmError, build_planner

    built = build_planner("uct", PlannerConfig(sims=1))
    with pytest.raises(StalmError, match="seed must be a non-negative integer"):
        built.solve(problems["P2"], seed=seed, time_budget_s=5.0)
