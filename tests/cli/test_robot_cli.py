"""``stalm robot list`` and ``stalm robot check``: the built-in robots with their sphere counts;
a robot's chain, limits, reach, spheres and the conservativeness check, exit 1 when the check
fails and exit 2 with one line for a file that is no robot."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stalm.motion.sphere_fit import LinkSpheres
from stalm.motion.sphere_fit_store import (
    RobotSpheres,
    beside_file,
    fit_robot_spheres,
    spheres_to_json,
)
from stalm.world.robot_loader import load_robot
from tests.cli_runner import run_cli
from tests.robot_files import write_test_arm


def test_robot_list_names_the_shipped_robots_with_their_sphere_counts(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "robot", "list") == 0
    lines = capsys.readouterr().out.splitlines()
    names = ["iiwa", "iiwa_gripper", "iiwa_gripper_table", "panda", "panda_table", "xarm6"]
    assert [line.split()[0] for line in lines] == [*names, "xarm6_table"]
    assert "7 joints  mobile  gripper" in lines[1] and "155 spheres" in lines[1]  # iiwa_gripper
    assert "7 joints  fixed   gripper" in lines[2] and "155 spheres" in lines[2]  # its table's
    assert "7 joints  mobile  gripper" in lines[3] and "124 spheres" in lines[3]  # panda
    assert "7 joints  fixed   gripper" in lines[4] and "124 spheres" in lines[4]  # panda_table
    assert "6 joints  mobile  gripper" in lines[5] and "94 spheres" in lines[5]  # xarm6
    assert len({line.index(" joints") for line in lines}) == 1  # a column for the longest name


def test_robot_check_prints_chain_limits_reach_spheres_and_the_check(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "robot", "check", "xarm6", "--samples", "500") == 0
    out = capsys.readouterr().out
    assert "chain     link_base -> xarm_gripper_base_link: 6 revolute joints (+1 fixed)" in out
    assert "  joint2                    -2.0590   2.0944   3.140   20.00  -1.7000" in out
    assert "mount     mobile: disc base r 0.3 m, h 0.35 m; arm 0.15 m ahead" in out
    assert "carry pose reaches 0.229 m from the base centre: inside the 0.3 m base" in out
    assert "gripper   opening 0.0869 m (fingers' collision geometry 0.0869 m apart" in out
    assert "reach     0." in out and "from the shoulder (joint2)" in out
    assert "spheres   94 (shipped, delta 0.02 m): link_base 12, link1 10" in out
    check = next(line for line in out.splitlines() if line.startswith("check"))
    assert check.endswith(": pass") and "(500 per link + hull vertices)" in check


def test_the_panda_check_says_its_carry_pose_leaves_the_base(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "robot", "check", "panda", "--samples", "200") == 0
    out = capsys.readouterr().out
    assert "carry pose reaches 0.325 m from the base centre: OUTSIDE the 0.3 m base" in out
    assert "lift 0.1 m/s, 0.5 m/s²" in out


def test_the_iiwa_check_says_it_has_no_gripper(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "robot", "check", "iiwa", "--samples", "200") == 0
    out = capsys.readouterr().out
    assert "gripper   none" in out and "chain     lbr_iiwa_link_0 -> lbr_iiwa_link_7: 7" in out
    assert "  velocity_limits: KUKA's LBR iiwa 14 R820 data sheet" in out


def test_the_iiwa_with_a_gripper_folds_inside_the_base(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "robot", "check", "iiwa_gripper", "--samples", "200") == 0
    out = capsys.readouterr().out
    assert "chain     lbr_iiwa_link_0 -> wsg_50_body: 7 revolute joints (+1 fixed)" in out
    assert "carry pose reaches 0.273 m from the base centre: inside the 0.3 m base" in out
    assert "gripper   opening 0.0850 m (fingers' collision geometry 0.0850 m apart" in out
    assert "spheres   155 (shipped, delta 0.02 m)" in out
    check = next(line for line in out.splitlines() if line.startswith("check"))
    assert check.endswith(": pass")


def test_a_failing_sphere_check_exits_1(monkeypatch, capsys, tmp_path: Path) -> None:
    robot = load_robot(str(write_test_arm(tmp_path)))
    good = fit_robot_spheres(robot, np.random.default_rng(0))
    shrunk = tuple(LinkSpheres(s.link, s.centres, s.radii * 0.9) for s in good.links)
    bad = RobotSpheres(good.robot, good.urdf_sha256, good.delta, shrunk)
    beside_file(robot).write_text(spheres_to_json(bad), encoding="utf-8")
    assert run_cli(monkeypatch, "robot", "check", robot.source, "--samples", "300") == 1
    out = capsys.readouterr().out
    assert "spheres   " in out and "(shipped, delta 0.02 m)" in out
    assert out.rstrip().endswith(": FAIL")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["robot", "check", "no_such_robot.yaml"], "cannot read robot file"),
        (["robot", "check", "panda", "--samples", "0"], "--samples must be at least 1, got 0"),
        (["robot", "check", "panda", "--seed", "-1"], "--seed must be a non-negative integer"),
    ],
)
def test_bad_robot_arguments_are_one_line_and_exit_2(
    monkeypatch, capsys, args: list[str], message: str
) -> None:
    assert run_cli(monkeypatch, *args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and message in err and "\n" not in err
