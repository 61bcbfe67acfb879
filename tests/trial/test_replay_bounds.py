"""A replayed plan is checked as the planner would have checked it (issue 46, items 1 and 2).

``data/p2_result.json`` is a real result (STaLM on P2). Each test forges one number of it the
way a hand-edited file would: a grasp orientation that composes to NaN, joints beyond the
Panda's limits, arm waypoints cut so the arm teleports, a joint or a base corner so far away
that the dense motion would fill the memory. Each is refused naming the step and the reason,
and the numbers are bounded before anything is densified.
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest

from stalm.domain.serialize import action_from_json
from stalm.errors import StalmError
from stalm.motion import arm_motion
from stalm.motion.base_motion import BasePath
from stalm.trial.replay import replay_plan, replay_result_json
from tests.cli_runner import run_cli

GENUINE_FILE = Path(__file__).parents[1] / "planners" / "data" / "p2_result.json"
GENUINE = json.loads(GENUINE_FILE.read_text())
OPEN_DOOR, PICK_BOTTLE2, PLACE_BOTTLE2 = 0, 1, 2
TWO_PI = 2 * math.pi
DENSE_LIMIT_IN_TESTS = 100_000
"""More configurations than any motion of these tests may be densified into: a forged number
must be refused before the motion is built, never after millions of configurations."""


@pytest.fixture
def data() -> dict[str, Any]:
    return copy.deepcopy(GENUINE)


@pytest.fixture(autouse=True)
def _interpolation_that_refuses_to_exhaust_memory(monkeypatch: pytest.MonkeyPatch) -> None:
    """A test double around the real interpolation and densification: it fails the test
    (quickly) where the real one would allocate a huge motion, as main did (minutes, GBs)."""

    def guarded_interpolate(start: Sequence[float], end: Sequence[float]) -> list[Any]:
        widest = max(abs(b - a) for a, b in zip(start, end, strict=True))
        assert widest / arm_motion.MAX_JOINT_STEP < DENSE_LIMIT_IN_TESTS, "a huge arm motion"
        return real_interpolate(start, end)

    def guarded_densify(real: Callable[[BasePath, float], list[Any]]) -> Callable[..., Any]:
        def densify(path: BasePath, resolution: float) -> list[Any]:
            assert path.length / resolution < DENSE_LIMIT_IN_TESTS, "a huge base path"
            return real(path, resolution)

        return densify

    real_interpolate = arm_motion.interpolate
    monkeypatch.setattr(arm_motion, "interpolate", guarded_interpolate)
    import stalm.domain.verify as verify
    import stalm.viz.animate as animate

    monkeypatch.setattr(verify, "densify", guarded_densify(verify.densify))
    monkeypatch.setattr(animate, "densify", guarded_densify(animate.densify))


def _refused(problems: dict[str, Any], data: dict[str, Any], step: int, *words: str) -> str:
    """The replay of ``data`` either refuses the file or fails at ``step`` (0-based), with a
    reason naming ``words``; never reaches the goal."""
    try:
        report = replay_result_json(problems["P2"], json.loads(json.dumps(data)))
    except StalmError as error:
        message = str(error)
        assert f"step {step + 1}" in message, message
    else:
        assert not report.reached_goal
        assert report.failed_step == step, report.reason
        message = str(report.reason)
    for word in words:
        assert word in message, message
    return message


# ---------------------------------------------------------------------------- item 1: poses


@pytest.mark.parametrize(
    "orientation",
    [
        [1e300, 1e300, 0.0, 0.0],  # composes to NaN: PyBullet then sees no contact at all
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 2.0],
        [0.5, 0.5, 0.5, 0.6],
    ],
)
def test_a_grasp_orientation_that_is_no_unit_quaternion_is_refused(
    problems, data, orientation
) -> None:
    data["plan"][PICK_BOTTLE2]["grasp"]["orientation"] = orientation
    _refused(problems, data, PICK_BOTTLE2, "grasp.orientation", "unit")


def test_a_grasp_far_outside_the_object_is_refused(problems, data) -> None:
    data["plan"][PICK_BOTTLE2]["grasp"]["position"] = [0.0, 0.0, 0.6]
    _refused(problems, data, PICK_BOTTLE2, "grasp.position")


def test_a_grasp_of_an_object_the_problem_lacks_fails_at_its_precondition(problems, data) -> None:
    data["plan"][PICK_BOTTLE2]["action"] = ["pick", "ghost"]
    _refused(problems, data, PICK_BOTTLE2, "'ghost' is not a movable object")


def test_a_placement_off_the_floor_is_refused(problems, data) -> None:
    data["plan"][PLACE_BOTTLE2]["placement"][0] = 40.0
    _refused(problems, data, PLACE_BOTTLE2, "placement", "floor")


@pytest.mark.parametrize(
    ("step", "change", "named"),
    [
        (PICK_BOTTLE2, lambda s: s["base_path"][2].__setitem__(2, 1e300), "base_path[2]"),
        (PICK_BOTTLE2, lambda s: s.update(pitch=5000.0), "pitch"),
        (PICK_BOTTLE2, lambda s: s.update(yaw=-1e300), "yaw"),
        (PLACE_BOTTLE2, lambda s: s["placement"].__setitem__(2, -1.0), "height"),
    ],
)
def test_angles_and_heights_no_problem_holds_are_refused(
    problems, data, step, change, named
) -> None:
    change(data["plan"][step])
    _refused(problems, data, step, named)


def test_a_placement_turned_from_how_the_hand_holds_the_object_fails(problems, data) -> None:
    data["plan"][PLACE_BOTTLE2]["placement"][3] += 0.5
    _refused(problems, data, PLACE_BOTTLE2, "turned")


def test_a_grasp_turned_from_how_the_object_stands_fails(problems, data) -> None:
    """A unit quaternion, but the object would be lifted tilted: its pose jumps."""
    x, y, z, w = data["plan"][PICK_BOTTLE2]["grasp"]["orientation"]
    data["plan"][PICK_BOTTLE2]["grasp"]["orientation"] = [y, -x, w, -z]  # turned by pi
    _refused(problems, data, PICK_BOTTLE2, "turned")


# ---------------------------------------------------------------------------- item 1: joints


def test_two_joints_at_two_pi_are_refused(problems, data) -> None:
    """Joints 4 and 6 of a waypoint at 2*pi: collision-free (main replayed it to the goal),
    but the Panda cannot turn them there."""
    data["plan"][PICK_BOTTLE2]["arm_waypoints"][2][5] = TWO_PI
    data["plan"][PICK_BOTTLE2]["arm_waypoints"][2][7] = TWO_PI
    _refused(problems, data, PICK_BOTTLE2, "arm_waypoints[2]", "limit")


def test_a_lift_beyond_its_range_is_refused(problems, data) -> None:
    data["plan"][OPEN_DOOR]["arm_waypoints"][1][0] = 2.5
    _refused(problems, data, OPEN_DOOR, "arm_waypoints[1]", "lift")


def test_a_key_configuration_beyond_the_limits_is_refused(problems, data) -> None:
    step = data["plan"][PICK_BOTTLE2]
    index = step["arm_waypoints"].index(step["grasp_conf"])
    for conf in (step["grasp_conf"], step["arm_waypoints"][index]):
        conf[1] += TWO_PI
    _refused(problems, data, PICK_BOTTLE2, "limit")


def test_a_handle_configuration_beyond_the_limits_is_refused(problems, data) -> None:
    data["plan"][OPEN_DOOR]["handle_conf"][6] = 4.0
    _refused(problems, data, OPEN_DOOR, "handle_conf", "joint 6")


def test_actions_given_to_replay_plan_directly_are_bounded_too(problems, data) -> None:
    """The API's replay_plan takes actions, not a file: it checks their bounds itself."""
    data["plan"][PICK_BOTTLE2]["arm_waypoints"][2][3] = 1e5
    actions = [action_from_json(step) for step in data["plan"]]
    report = replay_plan(problems["P2"], problems["P2"].initial_state, actions)
    assert report.failed_step == PICK_BOTTLE2 and "joint 3" in str(report.reason)


# ---------------------------------------------------------------------------- item 1: motions


def test_arm_waypoints_cut_to_the_grasp_alone_fail(problems, data) -> None:
    """The arm would 'teleport' from its carry pose to the grasp: main replayed it as
    reaching the goal."""
    step = data["plan"][PICK_BOTTLE2]
    step["arm_waypoints"] = [step["grasp_conf"]]
    _refused(problems, data, PICK_BOTTLE2, "arm", "start")


def test_an_arm_motion_that_does_not_end_folded_fails(problems, data) -> None:
    """Without its last waypoint the arm would drive off with its lift where it grasped."""
    del data["plan"][PLACE_BOTTLE2]["arm_waypoints"][-1]
    _refused(problems, data, PLACE_BOTTLE2, "arm", "end")


def test_an_arm_motion_that_starts_unfolded_fails(problems, data) -> None:
    del data["plan"][OPEN_DOOR]["arm_waypoints"][:2]
    _refused(problems, data, OPEN_DOOR, "arm", "start")


# ---------------------------------------------------------------------------- item 2: sizes


def test_a_joint_of_1e5_is_refused_before_the_motion_is_built(problems, data) -> None:
    data["plan"][PICK_BOTTLE2]["arm_waypoints"][2][3] = 1e5
    _refused(problems, data, PICK_BOTTLE2, "arm_waypoints[2]", "limit")


def test_a_base_corner_far_off_the_floor_is_refused_before_densifying(problems, data) -> None:
    data["plan"][PICK_BOTTLE2]["base_path"].insert(1, [1e7, 0.0, 0.0])
    _refused(problems, data, PICK_BOTTLE2, "base_path[1]", "floor")


def test_too_long_a_base_path_on_the_floor_is_refused(problems, data) -> None:
    """Every corner on the floor, but thousands of crossings: the dense path's length is
    known from the corners before any of it is made."""
    path = data["plan"][PICK_BOTTLE2]["base_path"]
    path[1:1] = [[-4.5, -4.5, 0.0], [4.5, 4.5, 0.0]] * 2000
    _refused(problems, data, PICK_BOTTLE2, "base path", "poses")


def test_too_many_arm_waypoints_within_the_limits_are_refused(problems, data) -> None:
    step = data["plan"][PICK_BOTTLE2]
    folded = step["arm_waypoints"][1]
    stretched = [folded[0], 2.8, 1.7, 2.8, -0.1, 2.8, 3.7, 2.8]
    step["arm_waypoints"][2:2] = [stretched, folded] * 200
    _refused(problems, data, PICK_BOTTLE2, "arm motion", "configurations")


# ---------------------------------------------------------------------------- the commands


def _forged(tmp_path: Path, change: Callable[[dict[str, Any]], None]) -> Path:
    data = copy.deepcopy(GENUINE)
    change(data)
    path = tmp_path / "forged.json"
    path.write_text(json.dumps(data))
    return path


def _huge_joint(data: dict[str, Any]) -> None:
    data["plan"][PICK_BOTTLE2]["arm_waypoints"][2][3] = 1e5


def _far_corner(data: dict[str, Any]) -> None:
    data["plan"][PICK_BOTTLE2]["base_path"].insert(1, [1e7, 0.0, 0.0])


def _nan_grasp(data: dict[str, Any]) -> None:
    data["plan"][PICK_BOTTLE2]["grasp"]["orientation"] = [1e300, 1e300, 0.0, 0.0]


def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize("change", [_huge_joint, _far_corner, _nan_grasp])
def test_replay_view_and_export_refuse_a_forged_number_in_one_line(
    monkeypatch, capsys, tmp_path, change
) -> None:
    path = _forged(tmp_path, change)
    assert run_cli(monkeypatch, "replay", str(path)) == 2
    captured = capsys.readouterr()
    assert "step 2" in _one_line(captured.err)
    assert "goal is reached" not in captured.out
    for command, written in (("view", "forged.html"), ("export", "forged.trajectories.json")):
        output = tmp_path / written
        assert run_cli(monkeypatch, command, str(path), "-o", str(output)) == 2
        assert "step 2" in _one_line(capsys.readouterr().err)
        assert not output.exists()


def test_replay_refuses_a_cut_motion_with_the_step(monkeypatch, capsys, tmp_path) -> None:
    def cut(data: dict[str, Any]) -> None:
        step = data["plan"][PICK_BOTTLE2]
        step["arm_waypoints"] = [step["grasp_conf"]]

    assert run_cli(monkeypatch, "replay", str(_forged(tmp_path, cut))) == 1
    line = _one_line(capsys.readouterr().out)
    assert line.startswith("step 2 fails") and "arm" in line


@pytest.fixture
def _no_solving(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """A test double for the rerun's solve: a forged record must be refused before it."""

    def solve_and_report(*_: object, **__: object) -> None:
        raise AssertionError("the forged record was run")

    import stalm.cli.rerun_commands as rerun_commands

    monkeypatch.setattr(rerun_commands, "solve_and_report", solve_and_report)
    yield


@pytest.mark.usefixtures("_no_solving")
@pytest.mark.parametrize("change", [_huge_joint, _far_corner, _nan_grasp])
def test_rerun_refuses_a_record_with_a_forged_plan(monkeypatch, capsys, tmp_path, change) -> None:
    def with_settings(data: dict[str, Any]) -> None:
        change(data)
        data["settings"] = {}

    path = _forged(tmp_path, with_settings)
    assert run_cli(monkeypatch, "rerun", str(path)) == 2
    assert "step 2" in _one_line(capsys.readouterr().err)
