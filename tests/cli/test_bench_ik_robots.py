"""``stalm bench ik --robot NAME``: each known arm against PyBullet's IK, and the refusals."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stalm.experiments import bench_ik
from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli


@pytest.fixture
def no_arm_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """Test doubles for both benchmark runs: any call fails the test, so each refusal is
    shown to come before the work."""

    def run_not_expected(*args: object, **kwargs: object) -> None:
        raise AssertionError("the benchmark ran although its arguments were refused")

    monkeypatch.setattr("stalm.experiments.bench_ik.run", run_not_expected)
    monkeypatch.setattr("stalm.experiments.bench_ik.bench_arm", run_not_expected)


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (
            ["--robot", "ur5"],
            "no robot 'ur5': give a robot file or one of iiwa, iiwa_gripper, iiwa_gripper_table, "
            "panda, panda_table, xarm6, xarm6_table",
        ),
        (["--robot", "xarm6", "P2"], "--robot xarm6 is benchmarked fixed at the origin"),
        (["--robot", "iiwa", "--attempts", "0"], "--attempts must be at least 1, got 0"),
    ],
)
def test_bad_robot_arguments_are_one_line_before_the_run(
    monkeypatch, capsys, no_arm_run, args: list[str], named: str
) -> None:
    assert run_cli(monkeypatch, "bench", "ik", *args) == 2
    assert named in one_error_line(capsys.readouterr().err)


def test_each_arm_is_benchmarked_against_pybullet(monkeypatch, capsys, tmp_path: Path) -> None:
    for robot, joints in (("xarm6", 6), ("iiwa", 7)):
        out = tmp_path / f"{robot}.json"
        args = ["bench", "ik", "--robot", robot, "--targets", "6", "--attempts", "20"]
        assert run_cli(monkeypatch, *args, "--json", str(out)) == 0
        (row,) = json.loads(out.read_text())
        assert (row["robot"], row["joints"], row["targets"], row["seeds"]) == (robot, joints, 6, 20)
        assert row["solve_s"] > 0 and row["reference_solve_s"] > 0
        assert 5 <= row["reached"] <= 6 and 3 <= row["reference_reached"] <= 6  # a live reference
        assert 0 <= row["missed"] <= row["reference_reached"]
        assert 1 <= row["mean_attempts"] <= 20
        assert f"IK of {robot}, fixed" in capsys.readouterr().out


def test_the_pandas_rows_count_what_the_compiled_ik_missed() -> None:
    row = bench_ik.bench_problem("P2", count=4, seed=1)
    assert row["missed"] == 0 and row["reached"] == 4
    assert bench_ik._missed([True, False, False], [True, True, False]) == 1
