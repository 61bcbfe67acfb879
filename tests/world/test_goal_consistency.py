"""Goals that no placement makes true together are refused when the problem is loaded
(issue 46, item 11): one object on two regions, a pair in two directions, related objects
put on two regions, and directions that go round in a cycle. ``stalm solve`` once spent its
whole budget on such a goal and said "timeout"."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from stalm.errors import StalmError
from stalm.world.goal_consistency import goal_contradiction
from stalm.world.problem import Problem
from stalm.world.problem_file import load_problem_file
from tests.cli_runner import run_cli


def _with_goal(problems: dict[str, Problem], tmp_path: Path, goal: list[list[str]]) -> Path:
    data = yaml.safe_load(Path(problems["P2"].source).read_text())
    data["goal"] = goal
    path = tmp_path / "goal.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


IMPOSSIBLE = [
    (
        [["salter", "on", "table1"], ["salter", "on", "table2"]],
        r"goal\[1\]: 'salter' on 'table2' contradicts goal\[0\] \('salter' on 'table1'\): an "
        r"object rests on one region",
    ),
    (
        [["salter", "left_of", "bottle1"], ["bottle1", "left_of", "salter"]],
        r"goal\[0\] \('salter' left_of 'bottle1'\), goal\[1\] \('bottle1' left_of 'salter'\) go "
        r"round in a cycle",
    ),
    (
        [["salter", "left_of", "bottle1"], ["salter", "right_of", "bottle1"]],
        r"goal\[0\] .*, goal\[1\] .* go round in a cycle",
    ),
    (
        [
            ["bottle3", "front_of", "bottle2"],
            ["salter", "behind_of", "bottle1"],
            ["bottle2", "front_of", "bottle1"],
            ["salter", "front_of", "bottle3"],
        ],
        r"goal\[0\] \('bottle3' front_of 'bottle2'\), goal\[3\] \('salter' front_of "
        r"'bottle3'\), goal\[1\] \('salter' behind_of 'bottle1'\), goal\[2\] \('bottle2' "
        r"front_of 'bottle1'\) go round in a cycle: no placement makes them all true",
    ),
    (
        [["salter", "left_of", "bottle1"], ["salter", "behind_of", "bottle1"]],
        r"goal\[1\]: 'salter' behind_of 'bottle1' contradicts goal\[0\] .*: a pair of objects "
        r"stands in one direction",
    ),
    (
        [
            ["salter", "on", "table2"],
            ["salter", "right_of", "bottle1"],
            ["bottle2", "front_of", "bottle1"],
            ["bottle2", "on", "counter2"],
        ],
        r"goal\[3\]: 'bottle2' on 'counter2' contradicts goal\[0\] \('salter' on 'table2'\): the "
        r"relative goals tie 'bottle2' to 'salter'",
    ),
]


@pytest.mark.parametrize(("goal", "message"), IMPOSSIBLE)
def test_an_impossible_goal_is_refused_naming_its_goals(
    problems: dict[str, Problem], tmp_path: Path, goal: list[list[str]], message: str
) -> None:
    path = _with_goal(problems, tmp_path, goal)
    with pytest.raises(StalmError, match=message) as caught:
        load_problem_file(path)
    assert str(caught.value).startswith(f"{path}: ") and "\n" not in str(caught.value)


@pytest.mark.parametrize(
    "goal",
    [
        [["salter", "on", "table2"], ["salter", "right_of", "bottle1"]],  # P2's own
        [["salter", "on", "table2"], ["salter", "on", "table2"]],  # said twice
        [["salter", "right_of", "bottle1"], ["bottle1", "left_of", "salter"]],  # one relation
        [["salter", "left_of", "bottle1"], ["bottle1", "left_of", "bottle2"]],  # a chain
        [  # two axes, no cycle: bottle2 behind both
            ["salter", "left_of", "bottle1"],
            ["bottle2", "behind_of", "salter"],
            ["bottle1", "front_of", "bottle2"],
        ],
        [["bottle2", "left_of", "bottle3"], ["bottle1", "on", "counter2"]],  # apart
    ],
)
def test_a_possible_goal_loads(
    problems: dict[str, Problem], tmp_path: Path, goal: list[list[str]]
) -> None:
    load_problem_file(_with_goal(problems, tmp_path, goal))


def test_the_shipped_problems_goals_are_consistent(problems: dict[str, Problem]) -> None:
    for problem in problems.values():
        assert goal_contradiction([(g.obj, g.direction, g.ref) for g in problem.goal]) is None


def test_a_cycle_through_many_objects_is_found_quickly() -> None:
    """A thousand objects in a ring of left_of: a depth-first search, not a recursion."""
    ring = [(f"o{i}", "left_of", f"o{(i + 1) % 1000}") for i in range(1000)]
    found = goal_contradiction(ring)
    assert found is not None and found.startswith("goal[0] ('o0' left_of 'o1'), goal[1]")
    assert "and 994 more go round in a cycle" in found and len(found) < 400
    assert goal_contradiction(ring[:-1]) is None


def test_problems_file_refuses_a_contradictory_goal(
    problems: dict[str, Problem], tmp_path: Path, monkeypatch, capsys
) -> None:
    goal, _ = IMPOSSIBLE[0]
    path = _with_goal(problems, tmp_path, goal)
    assert run_cli(monkeypatch, "problems", "--file", str(path)) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "contradicts goal[0]" in err and "\n" not in err
