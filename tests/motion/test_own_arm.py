"""An arm no library ships, planned for end to end: the tests write the reacher (a 6-joint arm
of boxes and cylinders with a two-finger gripper, its root a mount plate below the arm's base
link, :mod:`tests.robot_files`), its robot file, and a problem naming that file by a path
relative to the problem file. ``stalm robot check`` passes, the spheres the planner moves
contain every link where the simulator puts it, the carry pose folds over the base, a record
of the problem reopens from another folder, and ``stalm solve`` solves it and ``stalm replay``
reaches the goal."""

from __future__ import annotations

import itertools
import json
import re
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
import yaml
from jsonschema import Draft202012Validator

from stalm.errors import StalmError
from stalm.motion.arm_model import UrdfArm, arm_of
from stalm.motion.sphere_fit import CONTACT_MARGIN
from stalm.trial.result_schema import result_schema
from stalm.world.link_shapes import link_convex_parts, transformed
from stalm.world.problem import load_problem
from stalm.world.problem_record import PROBLEM_FOLDER_FIELD, problem_fields, record_problem
from stalm.world.robot_facts import robot_facts
from stalm.world.robot_urdf import UrdfBody, urdf_body
from stalm.world.scene import Sim
from tests.cli_runner import run_cli
from tests.robot_files import REACHER_CARRY, reacher_robot, write_reacher_problem

CARRY_TOP_M = 1.3
"""The folded arm stays below this at the carry lift (a shelf board's underside is higher)."""
SELF_CONTACT_M = 0.002
"""Links that are not neighbours may touch in the carry pose by at most this (m)."""
SOLVING_SEEDS = (0, 1, 2)
"""Seeds ``stalm solve`` solves the reacher's problem with (every one of 0-5 does)."""


@pytest.fixture
def problem_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The reacher's problem in ``tmp_path/problem``, its robot in ``problem/robots``; the
    sphere fit and the roadmaps cached in ``tmp_path/cache``."""
    monkeypatch.setenv("STALM_CACHE_DIR", str(tmp_path / "cache"))
    for name in ("STALM_LLM", "STALM_LLM_BASE_URL", "STALM_LLM_MODEL"):
        monkeypatch.delenv(name, raising=False)
    return write_reacher_problem(tmp_path / "problem")


def test_robot_check_passes_and_fits_the_spheres_into_the_cache(
    problem_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    robot_file = problem_file.parent / "robots" / "reacher.yaml"
    assert run_cli(monkeypatch, "robot", "check", str(robot_file), "--samples", "2000") == 0
    out = capsys.readouterr().out
    assert "chain     arm_base -> hand: 6 revolute joints (+1 fixed)" in out
    assert "carry pose reaches 0.218 m from the base centre: inside the 0.3 m base" in out
    assert "gripper   opening 0.0860 m (fingers' collision geometry 0.0860 m apart" in out
    reach = float(re.search(r"reach     ([0-9.]+) m", out).group(1))  # type: ignore[union-attr]
    assert 0.90 < reach <= 0.933 + 1e-3  # 0.34 + 0.30 + 0.10 + 0.08 + 0.03 + 0.083 stretched
    assert re.search(r"spheres   \d+ \(fitted, delta 0.02 m\): mount_plate \d+, arm_base", out)
    check = next(line for line in out.splitlines() if line.startswith("check"))
    assert check.endswith(": pass")
    assert "camera" not in out  # a link with a visual only has no spheres
    assert len(list((tmp_path / "cache" / "spheres").glob("*.json"))) == 1


def _arm_links(sim: Sim) -> UrdfBody:
    """The simulator's arm body, read as a URDF body is (its links by name)."""
    c = sim.client
    links = {p.getBodyInfo(sim.bodies.arm, physicsClientId=c)[0].decode(): -1}
    for index in range(p.getNumJoints(sim.bodies.arm, physicsClientId=c)):
        links[p.getJointInfo(sim.bodies.arm, index, physicsClientId=c)[12].decode()] = index
    return UrdfBody(c, sim.bodies.arm, links)


def test_the_spheres_contain_every_link_where_the_simulator_puts_it(problem_file: Path) -> None:
    """Points on each link's collision hulls (corners and points between them), at random
    configurations, lie inside the planner's spheres: the mount plate at the URDF's root, which
    no arm joint moves, as well as the links the joints move and the open fingers."""
    problem = load_problem(problem_file)
    rng = np.random.default_rng(4)
    limits = np.array(problem.robot.joint_limits)
    covered: set[str] = set()
    with Sim(problem.spec) as sim:
        arm = arm_of(sim)
        assert isinstance(arm, UrdfArm) and arm.dof == 6
        body = _arm_links(sim)
        for _ in range(25):
            stand = tuple(float(v) for v in rng.uniform(-1, 1, 3))
            lift, q = float(rng.uniform(0.55, 1.45)), rng.uniform(limits[:, 0], limits[:, 1])
            sim.set_arm(stand, lift, tuple(q))  # type: ignore[arg-type]
            frames = arm.frames(arm.base_frame(sim.arm_mount(stand, lift)), q)  # type: ignore[arg-type]
            model = arm.spheres
            centres = np.einsum("nij,nj->ni", frames[model.link][:, :3, :3], model.centre)
            centres += frames[model.link][:, :3, 3]
            for name, index in body.links.items():
                for hull in link_convex_parts(body, index):
                    weights = rng.dirichlet(np.ones(len(hull)) * 0.3, 40)
                    points = transformed(body.link_frame(index), np.vstack([hull, weights @ hull]))
                    gaps = np.linalg.norm(points[:, None] - centres[None], axis=2) - model.radius
                    assert gaps.min(axis=1).max() <= -CONTACT_MARGIN, name
                    covered.add(name)
    assert {"mount_plate", "arm_base", "upper_arm", "hand", "left_finger"} <= covered
    assert "camera" not in covered


def test_the_carry_pose_folds_over_the_base_without_touching_itself(problem_file: Path) -> None:
    problem = load_problem(problem_file)
    robot = problem.robot
    assert robot.spec.carry == REACHER_CARRY
    mount = robot.platform
    facts = robot_facts(robot, np.random.default_rng(0), samples=200)
    assert facts.carry_fits is True and facts.carry_radius is not None
    assert facts.carry_radius <= mount.base_radius - 0.05
    with Sim(problem.spec) as sim:
        arm = arm_of(sim)
        frames = arm.frames(
            arm.base_frame(sim.arm_mount((0.0, 0.0, 0.0), mount.carry_lift)),
            np.array(REACHER_CARRY),
        )
    model = arm.spheres
    centres = np.einsum("nij,nj->ni", frames[model.link][:, :3, :3], model.centre)
    centres += frames[model.link][:, :3, 3]
    assert (np.linalg.norm(centres[:, :2], axis=1) + model.radius).max() <= mount.base_radius
    assert (centres[:, 2] + model.radius).max() <= CARRY_TOP_M
    # folded, the arm stays above the base's top wherever the lift goes
    lowest = mount.lift_range[0] - mount.carry_lift
    assert (centres[:, 2] - model.radius).min() + lowest >= mount.base_height
    with urdf_body(robot.urdf_path) as loaded:
        loaded.set_joints(robot.arm_joints, REACHER_CARRY)
        parent = {
            index: int(loaded.joint_info(index)[16])
            for index in loaded.links.values()
            if index >= 0
        }
        pairs = [
            (a, b)
            for a, b in itertools.combinations(sorted(loaded.links.values()), 2)
            if parent.get(b) != a and parent.get(a) != b and parent.get(a) != parent.get(b)
        ]
        deepest = min(
            min((point[8] for point in p.getClosestPoints(
                loaded.body, loaded.body, 0.01, linkIndexA=a, linkIndexB=b,
                physicsClientId=loaded.client)), default=np.inf)
            for a, b in pairs
        )  # fmt: skip
    assert deepest >= -SELF_CONTACT_M


def test_a_record_of_the_problem_reopens_from_another_folder(
    problem_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The problem names its robot file relative to itself: a record of it says where that
    is, so the embedded problem loads the same robot wherever it is reopened."""
    monkeypatch.chdir(problem_file.parent)
    problem = load_problem(problem_file.name)  # a relative path: its folder is the working one
    assert problem.spec.robot.file == "robots/reacher.yaml"
    record = json.loads(json.dumps(problem_fields(problem)))
    assert record["problem_folder"] == str(problem_file.parent.resolve())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    again = record_problem(record, "reach1.json")
    assert again.robot.name == "reacher" and again.content_hash == problem.content_hash
    assert again.robot.urdf_path == problem.robot.urdf_path.resolve()


def test_only_a_problem_naming_a_relative_path_records_a_folder_and_a_bad_one_is_refused(
    problem_file: Path,
) -> None:
    assert PROBLEM_FOLDER_FIELD not in problem_fields(load_problem("P2"))  # records as before
    assert PROBLEM_FOLDER_FIELD not in problem_fields(load_problem("P2").with_robot("xarm6"))
    absolute = load_problem("P2").with_robot(str(problem_file.parent / "robots" / "reacher.yaml"))
    assert absolute.spec.files_folder is None
    record = problem_fields(load_problem(problem_file))
    for bad in (5, "", "x" * 5000):
        with pytest.raises(StalmError, match=r"r\.json: problem_folder: not a folder.s path"):
            record_problem({**record, PROBLEM_FOLDER_FIELD: bad}, "r.json")


def test_the_robots_page_shows_the_reachers_robot_file() -> None:
    page = (Path(__file__).resolve().parents[2] / "docs" / "robots.md").read_text()
    shown = next(
        yaml.safe_load(block)
        for block in re.findall(r"```yaml\n(.*?)```", page, flags=re.DOTALL)
        if block.startswith("name: reacher")
    )
    assert shown == {k: v for k, v in reacher_robot().items() if k != "sources"}


def test_stalm_solves_the_problem_and_the_replay_reaches_the_goal(
    problem_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    for seed in SOLVING_SEEDS:
        result = tmp_path / f"reach1-{seed}.json"
        args = ("solve", str(problem_file), "--seed", str(seed), "--json", str(result), "-q")
        assert run_cli(monkeypatch, *args) == 0, seed
        record = json.loads(result.read_text(encoding="utf-8"))
        assert record["success"] is True and record["termination"] == "goal"
        assert [step["action"][0] for step in record["plan"]] == ["pick", "place"] * 2
        assert all(len(step["arm_waypoints"][0]) == 7 for step in record["plan"])  # lift + 6
        assert record["problem_folder"] == str(problem_file.parent.resolve())
        assert list(Draft202012Validator(result_schema()).iter_errors(record)) == []
        capsys.readouterr()
        monkeypatch.chdir(elsewhere)
        assert run_cli(monkeypatch, "replay", str(result)) == 0, seed
        assert "the goal is reached" in capsys.readouterr().out


def test_the_page_draws_the_arm_of_boxes(
    problem_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``stalm view`` draws any arm by its joints' links, grasp point and fingers (the
    Panda's link numbers, which this arm does not have, broke it)."""
    from stalm.viz.view_data import view_data

    result, page = tmp_path / "reach1.json", tmp_path / "reach1.html"
    args = ("solve", str(problem_file), "--seed", str(SOLVING_SEEDS[0]), "--json", str(result))
    assert run_cli(monkeypatch, *args, "-q") == 0
    assert run_cli(monkeypatch, "view", str(result), "-o", str(page)) == 0
    assert page.read_text().startswith("<!DOCTYPE html>")
    data = view_data(load_problem(problem_file), json.loads(result.read_text()))
    arm = data["frames"]["arm"][0]
    # the mount, six joints' links, the grasp point, a gap, the finger bar
    assert len(arm) == 1 + 6 + 1 + 1 + 3 and arm[8] is None
