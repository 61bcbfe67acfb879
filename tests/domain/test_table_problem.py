"""TABLE1, the tabletop problem: an arm fixed at a table's edge works a table and two shelves
from its one pose. What its description claims is checked where solves meet it, for the fixed
arms: the base never moves, the red can is hidden behind the blue one for the Panda and the
xArm (the blue can is moved before the red one is picked), and the plan passes the physics
check."""

from __future__ import annotations

from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.world.problem import load_problem
from tests.domain.shipped_solves import assert_physics_passes, solve_and_replay

OCCLUDED_FOR = {"panda_table", "xarm6_table"}
"""The arms whose every sampled pick of the red can touches the blue can (the predicates'
PickOccludedBy(red_can, blue_can)); the iiwa, longer-armed, reaches past it."""


@pytest.mark.parametrize("robot", ["panda_table", "xarm6_table", "iiwa_gripper_table"])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_fixed_arm_solves_table1_from_its_one_pose(
    monkeypatch, tmp_path: Path, robot: str, seed: int
) -> None:
    solve = solve_and_replay(monkeypatch, tmp_path, "TABLE1", seed, robot)
    fixed = solve.problem.robot.platform.fixed_at
    assert fixed == (0.0, 0.0, 0.0)
    for action in solve.replay.actions:
        assert set(action.params.base_path.corners) == {fixed}  # the base never moves
    words = solve.words
    if robot in OCCLUDED_FOR:
        assert words.index("pick(blue_can)") < words.index("pick(red_can)")
    else:  # the iiwa's grasps pass the blue can: its plan is the 4 goal moves
        assert "pick(blue_can)" not in words and len(words) == 4
    assert "place(red_can, on, shelf_left)" in words
    assert_physics_passes(solve)


def test_a_fixed_arm_is_refused_where_it_would_have_to_move() -> None:
    with pytest.raises(StalmError, match=r"fixed at \[0.0, 0.0, 0.0\].*P2's robot.base"):
        load_problem("P2").with_robot("xarm6_table")
    with pytest.raises(StalmError, match="'iiwa' has no gripper"):
        load_problem("TABLE1").with_robot("iiwa")
    table = load_problem("TABLE1")
    assert table.robot.name == "panda_table" and table.spec.robot.file == "panda_table"
    assert table.robot.platform.lift_range == (0.8, 0.8)


def test_a_fixed_arm_with_a_door_to_drive_to_is_refused(tmp_path: Path) -> None:
    import yaml

    data = yaml.safe_load(Path(load_problem("TABLE1").source).read_text())
    data["doors"] = [
        {
            "name": "cupboard",
            "hinge": [1.2, -0.4],
            "width": 0.8,
            "height": 2.0,
            "thickness": 0.05,
            "closed_yaw": 1.570796,
            "open_yaw": 0.0,
            "handle_height": 1.05,
            "base_poses": [[1.0, 0.5, 1.570796]],
        }
    ]
    path = tmp_path / "table_door.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(StalmError, match=r"door 'cupboard''s base_poses\[0\]"):
        load_problem(path).with_robot("xarm6_table")


def test_a_problem_naming_a_missing_robot_says_so_when_it_loads(tmp_path: Path) -> None:
    text = Path(load_problem("TABLE1").source).read_text()
    path = tmp_path / "nobody.yaml"
    path.write_text(text.replace("file: panda_table", "file: nobody"))
    with pytest.raises(StalmError, match=r"nobody.yaml: robot.file: no robot 'nobody'"):
        load_problem(path)


def test_the_problem_hash_covers_the_robot_files_content(tmp_path: Path) -> None:
    robots = tmp_path / "robots"
    robots.mkdir()
    shipped = Path(load_problem("TABLE1").robot.source)
    text = Path(load_problem("TABLE1").source).read_text()
    problem = tmp_path / "table.yaml"
    problem.write_text(text.replace("file: panda_table", "file: robots/arm.yaml"))
    (robots / "arm.yaml").write_text(shipped.read_text().replace("name: panda_table", "name: arm"))
    before = load_problem(problem).content_hash
    from stalm.world.robot_loader import robot_named

    robot_named.cache_clear()
    (robots / "arm.yaml").write_text(
        shipped.read_text()
        .replace("name: panda_table", "name: arm")
        .replace("1.5, 0.785]", "1.4, 0.785]", 1)
    )
    assert load_problem(problem).content_hash != before
