"""``stalm replay`` cannot be fooled by the file it replays (issue 16, item 2).

``data/p2_result.json`` is a real result: STaLM solving P2 with a scripted proposer (seed 0),
written by ``stalm solve --json`` before results carried the problem's hash. Each test forges
one part of it; the genuine file must still replay to the goal.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import pytest

from stalm.errors import StalmError
from stalm.trial.replay import replay_result_json
from stalm.world.problem import Problem

GENUINE_FILE = Path(__file__).parents[1] / "planners" / "data" / "p2_result.json"
GENUINE = json.loads(GENUINE_FILE.read_text())
PICK_BOTTLE2, PLACE_BOTTLE2 = 1, 2


@pytest.fixture
def data() -> dict[str, Any]:
    return copy.deepcopy(GENUINE)


def test_the_genuine_result_replays_to_the_goal(problems, data) -> None:
    report = replay_result_json(problems["P2"], data)
    assert report.reached_goal and report.steps_executed == 7
    assert any("no problem hash" in warning for warning in report.warnings)


def test_a_result_with_the_right_hash_replays_without_warnings(problems, data) -> None:
    data["problem_hash"] = problems["P2"].content_hash
    report = replay_result_json(problems["P2"], data)
    assert report.reached_goal and report.warnings == ()


def test_a_result_for_another_problem_is_refused(problems, data) -> None:
    data["problem_hash"] = problems["P4"].content_hash
    with pytest.raises(StalmError, match="hash"):
        replay_result_json(problems["P2"], data)


def test_the_stored_initial_state_is_not_trusted(problems, data) -> None:
    data["plan"] = []
    data["initial_state"] = data["final_state"]  # "starts" at the goal
    report = replay_result_json(problems["P2"], data)
    assert not report.reached_goal
    assert any("initial_state" in warning for warning in report.warnings)


def test_an_object_moved_into_a_wall_in_the_stored_state_changes_nothing(problems, data) -> None:
    data["initial_state"]["poses"]["bottle1"] = [-5.05, 0.0, 1.0, 0.0]  # inside wall_west
    report = replay_result_json(problems["P2"], data)
    assert report.reached_goal and report.states[0] == problems["P2"].initial_state


@pytest.mark.parametrize(
    "where",
    [
        ("arm_waypoints", 2, 3),
        ("base_path", 1, 0),
        ("grasp_conf", 4),
        ("grasp", "position", 0),
    ],
)
def test_non_finite_numbers_are_refused(problems, data, where) -> None:
    for bad in (math.nan, math.inf):
        forged = copy.deepcopy(data)
        target = forged["plan"][PICK_BOTTLE2]
        for key in where[:-1]:
            target = target[key]
        target[where[-1]] = bad
        with pytest.raises(StalmError, match="step 2") as error:
            replay_result_json(problems["P2"], json.loads(json.dumps(forged)))
        assert "finite" in str(error.value)


def _fails_at(problem: Problem, data: dict[str, Any], step: int) -> str:
    report = replay_result_json(problem, data)
    assert not report.reached_goal and report.failed_step == step, report.reason
    assert report.reason
    return report.reason


def test_a_base_path_that_does_not_start_at_the_robot_fails(problems, data) -> None:
    data["plan"][PICK_BOTTLE2]["base_path"][0] = [2.0, 2.0, 0.0]  # a teleport
    assert "start" in _fails_at(problems["P2"], data, PICK_BOTTLE2)


def test_standing_somewhere_else_than_the_regions_pose_fails(problems, data) -> None:
    data["plan"][PICK_BOTTLE2]["base_path"].append([-3.5, -1.45, 3.141593])
    assert "standing pose" in _fails_at(problems["P2"], data, PICK_BOTTLE2)


def test_a_grasp_away_from_the_object_fails(problems, data) -> None:
    # 10 cm: within the bottle's size (farther is refused before the replay: test_replay_bounds)
    data["plan"][PICK_BOTTLE2]["grasp"]["position"][2] += 0.1
    assert "grasp" in _fails_at(problems["P2"], data, PICK_BOTTLE2)


def test_a_placement_off_the_named_region_fails(problems, data) -> None:
    data["plan"][PLACE_BOTTLE2]["placement"] = [3.0, 2.0, 1.0, 0.0]  # on table2, not counter1
    assert "counter1" in _fails_at(problems["P2"], data, PLACE_BOTTLE2)


def test_a_placement_inside_another_object_fails(problems, data) -> None:
    # bottle3 still stands on counter2; put bottle2 "on counter1" but where the hand ends up
    # is checked too, so forge both the placement and a consistent place_conf is not possible:
    # the placement alone moves, and the hand no longer holds the object there
    placement = data["plan"][PLACE_BOTTLE2]["placement"]
    placement[1] += 0.1
    assert "hand" in _fails_at(problems["P2"], data, PLACE_BOTTLE2)


def test_a_result_that_records_an_error_has_nothing_to_replay(problems) -> None:
    data = {"problem": "P2", "termination": "error", "error": "HTTP 401", "plan": []}
    with pytest.raises(StalmError, match="error"):
        replay_result_json(problems["P2"], data)


@pytest.mark.parametrize(
    "forge",
    [
        lambda d: d["plan"][1].update(action=["pick", 7]),
        lambda d: d["plan"][1].update(action=["pick", ["bottle2"]]),
        lambda d: d["plan"][1].update(grasp_conf=[0.0] * 8),  # not among the waypoints
        lambda d: d["plan"][1].update(base_path=[[0.0, 0.0]]),
        lambda d: d["plan"][1].update(arm_waypoints=[[0.0] * 3]),
        lambda d: d.update(plan={"not": "a list"}),
        lambda d: d["plan"].__setitem__(0, "open the door"),
    ],
)
def test_malformed_steps_are_one_clear_error(problems, data, forge) -> None:
    forge(data)
    with pytest.raises(StalmError):
        replay_result_json(problems["P2"], data)
