"""The geometric check of problem files: what loads but cannot be planned in (issue 16, item 6)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml

from stalm.cli.main import main
from stalm.errors import StalmError
from stalm.motion.problem_check import check_problem_geometry, problem_geometry_faults
from stalm.world.problem import Problem, load_problem


def _mutated(problems: dict[str, Problem], tmp_path: Path, mutate: object) -> Problem:
    data = yaml.safe_load(Path(problems["P2"].source).read_text())
    mutate(data)  # type: ignore[operator]
    path = tmp_path / "p2-changed.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_problem(path)  # loads: every field is fine on its own


def _wall(name: str, x: float, y: float, sx: float, sy: float) -> dict[str, object]:
    return {"name": name, "center": [x, y, 1.1], "size": [sx, sy, 2.2]}


def test_the_six_problems_pass(problems: dict[str, Problem]) -> None:
    for name, problem in problems.items():
        assert problem_geometry_faults(problem) == [], name


def test_a_robot_starting_inside_a_wall(problems, tmp_path) -> None:
    problem = _mutated(problems, tmp_path, lambda d: d["robot"].update(base=[-1.5, 2.0, 0.0]))
    faults = problem_geometry_faults(problem)
    assert any(f.startswith("robot.base") and "wall_divider_north" in f for f in faults)


def test_an_object_starting_inside_a_post(problems, tmp_path) -> None:
    # salter stands on counter2 at u = 0.16 (region yaw pi): x = -4.76, y = -1.45
    problem = _mutated(
        problems, tmp_path, lambda d: d["walls"].append(_wall("post", -4.76, -1.45, 0.02, 0.02))
    )
    faults = problem_geometry_faults(problem)
    assert any("objects[0] ('salter')" in f and "'post'" in f for f in faults)


def _table2_in_the_north_wall(d: dict) -> None:
    # table2 (regions[6], yaw pi/2: its u axis is the world's +y) centred on wall_north's
    # inner face, its standing pose 0.65 m in front; bottle1 (objects[1]) stays clear of the
    # wall at u = -0.2, so no object starts inside anything (issue 42, finding 5)
    d["regions"][6].update(center=[3.0, 5.0], base_pose=[3.0, 4.35, 1.570796])
    d["objects"][1]["at"] = [-0.2, 0.0]


def test_a_region_inside_a_wall(problems, tmp_path) -> None:
    faults = problem_geometry_faults(_mutated(problems, tmp_path, _table2_in_the_north_wall))
    assert "regions[6] ('table2'): stands inside 'wall_north'" in faults


def test_a_region_inside_a_wall_is_an_error_of_the_cli(
    problems, tmp_path, monkeypatch, capsys
) -> None:
    problem = _mutated(problems, tmp_path, _table2_in_the_north_wall)
    assert _run_cli(monkeypatch, "problems", "--file", problem.source) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "('table2'): stands inside 'wall_north'" in err


def test_a_standing_pose_inside_a_wall(problems, tmp_path) -> None:
    def move(d: dict) -> None:
        d["regions"][5]["base_pose"] = [-1.5, 2.0, 0.0]  # table1's pose, inside the divider

    faults = problem_geometry_faults(_mutated(problems, tmp_path, move))
    assert any(f.startswith("regions[5].base_pose ('table1')") for f in faults)


def test_a_standing_pose_the_base_cannot_reach(problems, tmp_path) -> None:
    def closet(d: dict) -> None:
        # a closed 1.3 m square room in the hall, table2's standing pose inside it
        d["walls"] += [
            _wall("closet_w", 0.3, 3.5, 0.1, 1.5),
            _wall("closet_e", 1.7, 3.5, 0.1, 1.5),
            _wall("closet_s", 1.0, 2.8, 1.5, 0.1),
            _wall("closet_n", 1.0, 4.2, 1.5, 0.1),
        ]
        d["regions"][6]["base_pose"] = [1.0, 3.5, 0.0]

    problem = _mutated(problems, tmp_path, closet)
    with pytest.raises(StalmError) as caught:
        check_problem_geometry(problem)
    message = str(caught.value)
    assert "regions[6].base_pose ('table2'): the base cannot drive there" in message
    assert "walled off from the start by 'closet_e', 'closet_n', 'closet_s', 'closet_w'" in message
    assert problem.source in message


def _run_cli(monkeypatch: pytest.MonkeyPatch, *args: str) -> int:
    monkeypatch.setattr(sys, "argv", ["stalm", *args])
    try:
        main()
    except SystemExit as done:
        return int(done.code or 0)
    return 0


def test_problems_file_and_solve_run_the_check(problems, tmp_path, monkeypatch, capsys) -> None:
    problem = _mutated(problems, tmp_path, lambda d: d["robot"].update(base=[-1.5, 2.0, 0.0]))
    assert _run_cli(monkeypatch, "problems", "--file", problem.source) == 2
    assert "robot.base" in capsys.readouterr().err
    assert _run_cli(monkeypatch, "problems", "--file", problem.source, "--no-check") == 0
    capsys.readouterr()
    code = _run_cli(monkeypatch, "solve", problem.source, "--planner", "uct", "--time-budget", "5")
    assert code == 2
    captured = capsys.readouterr()
    assert "robot.base" in captured.err and "plan (" not in captured.out


def _second_door(**changes: object):
    """A second door beside P2's kitchen door, changed by ``changes``."""

    def add(d: dict) -> None:
        door = {**d["doors"][0], "name": "second_door", **changes}
        d["doors"].append(door)

    return add


@pytest.mark.parametrize(
    ("changes", "fault"),
    [
        (
            {},
            "doors[1] ('second_door'): its panel closed passes through doors[0] ('kitchen_door') "
            "closed",
        ),
        (  # one hinge, closing the other way: open, it crosses the other at the hinge
            {"closed_yaw": -1.570796, "open_yaw": 3.141593},
            "doors[1] ('second_door'): its panel open passes through doors[0] "
            "('kitchen_door') closed",
        ),
        (  # a hinge of its own, whose open panel swings into the other one closed
            {"hinge": [-2.3, -3.8], "closed_yaw": 3.141593, "open_yaw": 0.0},
            "doors[1] ('second_door'): its panel open passes through doors[0] ('kitchen_door') "
            "closed",
        ),
    ],
)
def test_two_doors_through_each_other(problems, tmp_path, changes, fault) -> None:
    faults = problem_geometry_faults(_mutated(problems, tmp_path, _second_door(**changes)))
    assert fault in faults


def test_two_doors_apart_pass(problems, tmp_path) -> None:
    # a door of the same shape in the east wall's middle, standing poses on the floor
    changes = {"hinge": [4.9, 0.0], "closed_yaw": 1.570796, "open_yaw": 3.141593}
    faults = problem_geometry_faults(_mutated(problems, tmp_path, _second_door(**changes)))
    assert not any(f.startswith("doors[") for f in faults), faults
