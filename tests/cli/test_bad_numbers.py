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
    from stalm.api import StalmError, build_planner
    from tests.flat_settings import settings_of

    built = build_planner(planner, settings_of(proposer="symbolic", sims=1))
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
    from stalm.api import StalmError, build_planner
    from tests.flat_settings import settings_of

    built = build_planner("uct", settings_of(sims=1))
    with pytest.raises(StalmError, match="seed must be a non-negative integer"):
        built.solve(problems["P2"], seed=seed, time_budget_s=5.0)


# ---------------------------------------------------------------------------------------------
# item 11: one line where a traceback was


RESULT = Path(__file__).parent.parent / "planners" / "data" / "p2_result.json"


@pytest.mark.parametrize("constant", ["NaN", "Infinity", "-Infinity"])
def test_view_of_a_result_with_non_finite_times(monkeypatch, capsys, tmp_path, constant) -> None:
    text = RESULT.read_text()
    text = text.replace('"total": ', f'"total": {constant}, "was": ', 1)
    path = tmp_path / "r.json"
    path.write_text(text)
    assert run_cli(monkeypatch, "view", str(path), "-o", str(tmp_path / "r.html")) == 2
    line = one_error_line(capsys.readouterr().err)
    assert str(path) in line and constant.lstrip("-") in line
    assert not (tmp_path / "r.html").exists()


@pytest.mark.parametrize("command", ["view", "replay", "rerun", "export"])
def test_results_nested_very_deep(monkeypatch, capsys, tmp_path, command) -> None:
    path = tmp_path / "deep.json"
    path.write_text('{"problem": "P2", "plan": ' + "[" * 100_000 + "]" * 100_000 + "}")
    assert run_cli(monkeypatch, command, str(path)) == 2
    assert str(path) in one_error_line(capsys.readouterr().err)
    lines = tmp_path / "deep.jsonl"
    lines.write_text('{"key": "a"}\n' + "[" * 100_000 + "]" * 100_000 + "\n")
    assert run_cli(monkeypatch, "rerun", str(lines), "--key", "a") == 2
    assert str(lines) in one_error_line(capsys.readouterr().err)


def test_results_nested_just_below_the_json_limit(monkeypatch, capsys, tmp_path) -> None:
    """Deep enough for json to parse, too deep for the code that walks a plan."""
    path = tmp_path / "deep.json"
    data = '{"problem": "P2", "seed": 0, "settings": {}, "planner": "uct", "plan": '
    path.write_text(data + "[" * 900 + "]" * 900 + "}")
    for command in ("view", "replay", "rerun", "export"):
        assert run_cli(monkeypatch, command, str(path)) == 2
        assert "deep" in one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize("size", ["0", "-5", "30000"])
def test_render_sizes_out_of_range(monkeypatch, capsys, tmp_path, size) -> None:
    png = tmp_path / "x.png"
    assert run_cli(monkeypatch, "render", "P2", "--size", size, "-o", str(png)) == 2
    assert "--size" in one_error_line(capsys.readouterr().err)
    assert not png.exists()


@pytest.mark.parametrize(
    ("change", "named"),
    [
        (lambda d: d.update(floor=[[-1e308, -1e308], [1e308, 1e308]]), "floor"),
        (lambda d: d.update(floor=[[-400.0, -5.0], [400.0, 5.0]]), "floor"),
        (lambda d: d["walls"][0].update(size=[1e308, 0.1, 2.0]), "walls[0].size"),
        (lambda d: d["walls"][0].update(center=[1e308, 0.0, 1.0]), "walls[0].center"),
        (lambda d: d["regions"][0].update(size=[1e308, 1e308]), "regions[0].size"),
        (lambda d: d["regions"][0].update(top=1e308), "regions[0].top"),
        (lambda d: d["regions"][0].update(center=[-1e308, 0.0]), "regions[0].center"),
        (lambda d: d["objects"][0].update(height=1e308), "objects[0].height"),
        (lambda d: d["doors"][0].update(width=1e308), "doors[0].width"),
        (lambda d: d["objects"][0].update(yaw=1e308), "objects[0].yaw"),
        (lambda d: d["walls"][0].update(color=[0.5, 0.5, 0.5, 1e308]), "walls[0].color"),
    ],
)
def test_problem_sizes_and_coordinates_are_bounded(tmp_path, change, named) -> None:
    import yaml

    from stalm.errors import StalmError
    from stalm.world.problem import load_problem, shipped_problems_dir

    data = yaml.safe_load((shipped_problems_dir() / "p2.yaml").read_text())
    change(data)
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(StalmError) as error:
        load_problem(path)
    assert named in str(error.value)
    assert len(str(error.value).splitlines()) <= 7  # one per field at fault, at most 6
