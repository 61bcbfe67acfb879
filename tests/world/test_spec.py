from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from stalm.errors import StalmError
from stalm.world.problem import Problem, load_problem
from stalm.world.problem_file import load_problem_file, parse_problem

PAPER_PLACEMENT_COUNTS = {"P1": 31, "P2": 23, "P3": 50, "P4": 27, "P6": 27}


def test_every_problem_loads_with_the_papers_placement_count(problems: dict[str, Problem]) -> None:
    for name, count in PAPER_PLACEMENT_COUNTS.items():
        assert problems[name].spec.placement_count == count, name
    # P5: the authors' roster gives 24 (the paper prints 21), see research/scenarios.md
    assert problems["P5"].spec.placement_count == 24


def test_problems_keep_the_scenario_names_and_goals(problems: dict[str, Problem]) -> None:
    p5 = problems["P5"]
    assert [r.name for r in p5.spec.regions] == ["counter1", "counter2", "counter3", "counter5"]
    assert {(g.obj, g.direction, g.ref) for g in p5.goal} == {
        ("coke", "on", "counter1"),
        ("sprite", "on", "counter1"),
        ("beef_grill", "on", "counter1"),
    }
    p2 = problems["P2"]
    assert [(g.obj, g.direction, g.ref) for g in p2.goal] == [
        ("salter", "on", "table2"),
        ("salter", "right_of", "bottle1"),
    ]
    assert all(pr.spec.doors[0].name == "kitchen_door" for pr in problems.values())


def test_problem_lookup_is_case_insensitive_and_accepts_paths(problems: dict[str, Problem]) -> None:
    assert load_problem("p2").spec == problems["P2"].spec
    assert load_problem(Path(problems["P2"].source)).spec == problems["P2"].spec


def test_unknown_problem_names_the_available_ones() -> None:
    with pytest.raises(StalmError, match=r"unknown problem 'P9'.*available: .*P1"):
        load_problem("P9")


def _p2_data(problems: dict[str, Problem]) -> dict[str, object]:
    return yaml.safe_load(Path(problems["P2"].source).read_text())


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d["objects"][0].update(radius=-0.1), r"objects\[0\]\.radius: .*greater than 0"),
        (
            lambda d: d["objects"][0].update(on="nowhere"),
            r"objects\[0\]\.on: 'nowhere' is not a region",
        ),
        (lambda d: d.pop("robot"), r"robot: Field required"),
        (
            lambda d: d["goal"].append(["ghost", "on", "table1"]),
            r"goal\[2\]\.obj: 'ghost' is not a movable",
        ),
        (
            lambda d: d["goal"].append(["salter", "on", "bottle1"]),
            r"goal\[2\]\.ref: 'on' needs a region",
        ),
        (
            lambda d: d["objects"][1].update(name="salter"),
            r"objects\[1\]\.name: 'salter' is already used",
        ),
        (
            lambda d: d["objects"][0].update(at=[3.0, 0.0]),
            r"objects\[0\]\.at: .*outside the usable area .*its footprint is 0.066 x 0.066 m",
        ),
        (
            lambda d: d["objects"][0].update(colour=[1, 0, 0, 1]),
            r"objects\.0\.colour|objects\[0\]\.colour",
        ),
        (lambda d: d["objects"][0].update(shape="cube"), r"objects\[0\]\.shape"),
        (lambda d: d["regions"][0].update(usable=[9.0, 9.0]), r"regions\[0\]: usable area"),
    ],
)
def test_bad_problem_files_name_the_file_and_field(
    problems: dict[str, Problem], tmp_path: Path, mutate: object, message: str
) -> None:
    data = _p2_data(problems)
    mutate(data)  # type: ignore[operator]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(StalmError, match=message) as caught:
        load_problem_file(path)
    assert str(path) in str(caught.value)


def test_unreadable_and_malformed_files(tmp_path: Path) -> None:
    with pytest.raises(StalmError, match="cannot read problem file"):
        load_problem_file(tmp_path / "missing.yaml")
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: [unclosed\n")
    with pytest.raises(StalmError, match="not valid YAML"):
        load_problem_file(broken)
    with pytest.raises(StalmError, match="must be a mapping"):
        parse_problem(["a", "list"], "list.yaml")


def test_a_user_problem_file_with_more_objects_works(
    problems: dict[str, Problem], tmp_path: Path
) -> None:
    data = _p2_data(problems)
    data["name"] = "mine"
    data["objects"].append(  # type: ignore[union-attr]
        {
            "name": "mug",
            "shape": "cylinder",
            "radius": 0.04,
            "height": 0.1,
            "on": "table1",
            "at": [0.0, 0.3],
        }
    )
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(data))
    mine = load_problem(path)
    assert mine.spec.placement_count == 7 + 4 * 5
    assert mine.initial_state.has_pose("mug")


# --- Issue 16: files that parse but describe an impossible or unsafe problem ------------------


def _load_mutated(problems: dict[str, Problem], tmp_path: Path, mutate: object) -> None:
    data = _p2_data(problems)
    mutate(data)  # type: ignore[operator]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    load_problem_file(path)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d["objects"][0].update(at=[float("nan"), 0.0]), r"objects\[0\]\.at.*finite"),
        (lambda d: d["regions"][0].update(top=float("inf")), r"regions\[0\]\.top.*finite"),
        (lambda d: d["robot"].update(base=[0.5, float("-inf"), 0.0]), r"robot\.base.*finite"),
        (lambda d: d["doors"][0].update(width=float("nan")), r"doors\[0\]\.width"),
        (lambda d: d.update(time_budget_s=float("nan")), r"time_budget_s"),
        (
            lambda d: d["objects"][2].update(at=d["objects"][3]["at"]),
            r"objects\[3\]\.at: 'bottle3' overlaps 'bottle2'",
        ),
        (
            lambda d: d["objects"][0].update(at=[0.12, 0.03]),
            r"overlaps 'salter'",
        ),
        (lambda d: d["objects"][0].update(name=")("), r"objects\[0\]\.name: '\)\(' is not a name"),
        (lambda d: d["regions"][1].update(name="a b"), r"regions\[1\]\.name: 'a b' is not a"),
        (lambda d: d["doors"][0].update(name="door;rm"), r"doors\[0\]\.name"),
        (lambda d: d["walls"][0].update(name="x" * 65), r"walls\[0\]\.name"),
        (lambda d: d["regions"][0].update(room="[/]"), r"regions\[0\]\.room"),
        (lambda d: d.update(name="P 2"), r"name: 'P 2' is not a name"),
        (
            lambda d: d["objects"][1].update(name="SALTER"),
            r"objects\[1\]\.name: 'SALTER' is already used",
        ),
        (lambda d: d["robot"].update(base=[7.0, 0.0, 0.0]), r"robot\.base: .*off the floor"),
        (
            lambda d: d["regions"][2].update(base_pose=[0.0, -6.0, 0.0]),
            r"regions\[2\]\.base_pose: .*off the floor",
        ),
    ],
)
def test_problem_files_that_validate_but_are_wrong_are_refused(
    problems: dict[str, Problem], tmp_path: Path, mutate: object, message: str
) -> None:
    with pytest.raises(StalmError, match=message):
        _load_mutated(problems, tmp_path, mutate)


def test_a_grill_beside_a_can_is_fine_but_on_it_is_not(
    problems: dict[str, Problem], tmp_path: Path
) -> None:
    p5 = yaml.safe_load(Path(problems["P5"].source).read_text())
    grills = [o for o in p5["objects"] if o["shape"] == "grill"]
    assert grills  # P5's grill stands beside other objects: that loads
    grill = grills[0]
    can = {"name": "can", "shape": "cylinder", "radius": 0.03, "height": 0.1, "on": grill["on"]}
    p5["objects"].append({**can, "at": list(grill["at"])})
    path = tmp_path / "p5.yaml"
    path.write_text(yaml.safe_dump(p5))
    with pytest.raises(StalmError, match=f"'can' overlaps '{grill['name']}'"):
        load_problem_file(path)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("name: 2001-02-30\n", "not valid YAML"),
        ("a: &a [*a]\n", "more than"),
        (
            "".join(
                f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]\n" for i in range(1, 12)
            ).replace("*l0", "0"),
            "more than",
        ),
        ("[" * 5000 + "]" * 5000, "not valid YAML|mapping"),
        ("a: '" + "x" * 1_000_001 + "'\n", "too long"),
    ],
)
def test_hostile_yaml_is_refused_quickly(tmp_path: Path, text: str, message: str) -> None:
    import time

    path = tmp_path / "hostile.yaml"
    path.write_text(text)
    started = time.perf_counter()
    with pytest.raises(StalmError, match=message):
        load_problem_file(path)
    assert time.perf_counter() - started < 2.0


def test_a_bare_on_gets_a_one_line_hint(tmp_path: Path, monkeypatch, capsys) -> None:
    """YAML reads an unquoted ``on: table2`` as the key true: one line says to quote it, where
    pydantic alone gave two lines an object ("Keys should be strings"; issue 42, finding 5)."""
    from tests.cli_runner import run_cli

    text = Path(load_problem("P2").source).read_text()
    assert "'on': table2" in text and "'on': counter2" in text
    path = tmp_path / "bare_on.yaml"
    path.write_text(text.replace("'on': table2", "on: table2").replace("'on': counter2", "on: x"))
    assert run_cli(monkeypatch, "problems", "--file", str(path)) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err  # one line, as every error
    assert "objects[0]: a key reads as true" in err
    assert "quote it ('on': x) (and 3 more)" in err


def test_a_bare_on_in_a_goal_gets_the_hint() -> None:
    data = yaml.safe_load(Path(load_problem("P2").source).read_text())
    data["goal"][0] = yaml.safe_load("[salter, on, table2]")
    with pytest.raises(StalmError, match=r"^mine.yaml: goal\[0\]\[1\]: true is how YAML reads"):
        parse_problem(data, "mine.yaml")
