"""Fitted sphere models are conservative: points sampled on every link's collision hull lie
inside that link's spheres (the check), and so do the points where PyBullet's own rays hit the
link (a check that does not share the code that reads the shapes). The check can fail: a set
shrunk by a few millimetres does. The shipped sets are used without fitting; another robot is
fitted once and cached by its URDF's hash."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pybullet as p
import pytest

from stalm.errors import StalmError, StalmWarning
from stalm.motion.sphere_fit import CONTACT_MARGIN, LinkSpheres, check_spheres, fit_link_spheres
from stalm.motion.sphere_fit_store import (
    RobotSpheres,
    beside_file,
    cache_file,
    check_robot_spheres,
    robot_spheres,
    spheres_from_json,
    write_spheres_beside,
)
from stalm.world.link_shapes import body_convex_parts
from stalm.world.robot_description import Robot
from stalm.world.robot_facts import robot_facts
from stalm.world.robot_loader import builtin_robots, load_robot
from stalm.world.robot_urdf import urdf_body
from tests.robot_files import TEST_ARM_GAP, write_test_arm


def _ray_hits_outside_spheres(robot: Robot, spheres: RobotSpheres, rays: int = 300) -> float:
    """Cast ``rays`` rays at each link (in a random configuration) from a metre away towards
    its centre; the worst residual of PyBullet's hit points against the link's spheres (m,
    negative = every hit inside)."""
    rng = np.random.default_rng(7)
    model = spheres.by_link()
    worst = -np.inf
    with urdf_body(robot.urdf_path) as loaded:
        low, high = np.array(robot.joint_limits).T
        loaded.set_joints(robot.arm_joints, rng.uniform(low, high))
        for name, index in loaded.links.items():
            if name not in model:
                continue
            for other in loaded.links.values():  # the rays see this link alone
                group = 2 if other == index else 1
                p.setCollisionFilterGroupMask(
                    loaded.body, other, group, 3, physicsClientId=loaded.client
                )
            frame = loaded.link_frame(index)
            centre = frame[:3, :3] @ model[name].centres.mean(axis=0) + frame[:3, 3]
            directions = rng.normal(size=(rays, 3))
            directions /= np.linalg.norm(directions, axis=1, keepdims=True)
            starts = (centre + directions).tolist()
            results = p.rayTestBatch(
                starts,
                [centre.tolist()] * rays,
                collisionFilterMask=2,
                physicsClientId=loaded.client,
            )
            hits = np.array(
                [hit[3] for hit in results if hit[0] == loaded.body and hit[1] == index]
            )
            assert len(hits) > rays // 4, name  # the rays found the link
            local = (hits - frame[:3, 3]) @ frame[:3, :3]
            gaps = np.linalg.norm(local[:, None] - model[name].centres[None], axis=2)
            worst = max(worst, float((gaps - model[name].radii).min(axis=1).max()))
    return worst


@pytest.mark.parametrize("name", ["panda", "xarm6", "iiwa", "iiwa_gripper"])
def test_each_shipped_sphere_set_is_used_as_shipped_and_passes_the_check(name: str) -> None:
    robot = load_robot(name)
    spheres, origin = robot_spheres(robot)
    assert origin == "shipped"
    assert spheres.urdf_sha256 == robot.urdf_sha256
    check = check_robot_spheres(robot, spheres, np.random.default_rng(11))
    assert check.passed, (check.worst_link, check.worst_residual)
    assert check.worst_residual <= -CONTACT_MARGIN
    assert set(check.residual_by_link) == {link.link for link in spheres.links}
    assert check.samples > 5000 * len(spheres.links)  # every link sampled, vertices too
    assert _ray_hits_outside_spheres(robot, spheres) < 0.0


def test_a_shrunk_sphere_set_fails_the_check() -> None:
    robot = load_robot("xarm6")
    spheres, _ = robot_spheres(robot)
    shrunk = RobotSpheres(
        spheres.robot,
        spheres.urdf_sha256,
        spheres.delta,
        tuple(LinkSpheres(s.link, s.centres, s.radii - 0.004) for s in spheres.links),
    )
    check = check_robot_spheres(robot, shrunk, np.random.default_rng(11))
    assert not check.passed
    assert check.worst_residual > 0.001  # points left outside by more than a millimetre
    assert _ray_hits_outside_spheres(robot, shrunk) > 0.0
    without_a_link = RobotSpheres(
        spheres.robot, spheres.urdf_sha256, spheres.delta, spheres.links[1:]
    )
    missing = check_robot_spheres(robot, without_a_link, np.random.default_rng(11))
    assert missing.worst_residual == np.inf and missing.worst_link == spheres.links[0].link


def test_a_fit_is_reproducible_from_its_generator() -> None:
    robot = load_robot("panda")
    with urdf_body(robot.urdf_path) as loaded:
        parts = body_convex_parts(loaded)["panda_leftfinger"]
    first = fit_link_spheres("panda_leftfinger", parts, np.random.default_rng(3))
    second = fit_link_spheres("panda_leftfinger", parts, np.random.default_rng(3))
    assert np.array_equal(first.centres, second.centres)
    assert np.array_equal(first.radii, second.radii)
    smaller = fit_link_spheres("panda_leftfinger", parts, np.random.default_rng(3), delta=0.005)
    assert len(smaller.radii) > len(first.radii)  # a tighter bulge takes more spheres


def test_an_arm_the_tests_write_loads_fits_and_passes_the_check(tmp_path: Path) -> None:
    robot = load_robot(str(write_test_arm(tmp_path)))
    assert [joint.name for joint in robot.arm_joints] == ["j1", "j2", "j3", "j4", "j5", "j6"]
    assert [joint.kind for joint in robot.chain[-2:]] == ["fixed", "fixed"]
    assert robot.velocity_limits == (2.0,) * 6
    assert robot.joint_limits[2] == (-2.5, 2.5)
    facts = robot_facts(robot, np.random.default_rng(0), samples=300)
    assert facts.finger_gap == pytest.approx(TEST_ARM_GAP, abs=0.003)
    # shoulder (j2) to tool: 0.32 + 0.28 + 0.1 + 0.08 + 0.04 + 0.08 m when stretched out
    assert 0.8 < facts.reach <= 0.9 + 1e-9
    spheres, origin = robot_spheres(robot)
    assert origin == "fitted"
    assert {link.link for link in spheres.links} == {
        "base", "link1", "link2", "link3", "link4", "link5", "link6", "hand",
        "left_finger", "right_finger",
    }  # fmt: skip
    check = check_robot_spheres(robot, spheres, np.random.default_rng(5))
    assert check.passed, (check.worst_link, check.worst_residual)
    assert _ray_hits_outside_spheres(robot, spheres) < 0.0
    # written to the cache by the URDF's hash, and found there next time
    assert json.loads(cache_file(robot, spheres.delta).read_text())["urdf_sha256"] == (
        robot.urdf_sha256
    )
    again, origin = robot_spheres(robot)
    assert origin == "cache" and again.total == spheres.total
    assert not beside_file(robot).exists()


def test_a_changed_urdf_is_fitted_again_and_a_corrupt_cache_is_not_used(tmp_path: Path) -> None:
    robot = load_robot(str(write_test_arm(tmp_path)))
    first, _ = robot_spheres(robot)
    cache_file(robot, first.delta).write_text("{not json", encoding="utf-8")
    refitted, origin = robot_spheres(robot)
    assert origin == "fitted" and refitted.total == first.total
    urdf = tmp_path / "boxarm.urdf"
    urdf.write_text(urdf.read_text().replace('size="0.08 0.08 0.32"', 'size="0.1 0.1 0.32"'))
    changed = load_robot(str(tmp_path / "boxarm.yaml"))
    assert changed.urdf_sha256 != robot.urdf_sha256
    _, origin = robot_spheres(changed)
    assert origin == "fitted"


def test_every_builtin_robot_ships_its_spheres() -> None:
    """Beside its file, or (a robot file mounting a shipped arm otherwise: panda_table,
    xarm6_table) as the built-in robot of the same URDF's."""
    for name in builtin_robots():
        robot = load_robot(name)
        spheres, source = robot_spheres(robot)
        assert source == "shipped" and spheres.urdf_sha256 == robot.urdf_sha256
        if not name.endswith("_table"):
            assert beside_file(robot).is_file()


def test_a_flat_part_is_covered_too() -> None:
    """A plate modelled without thickness has no volume for a hull: it is joggled."""
    plate = np.array([[x, y, 0.0] for x in (-0.1, 0.1) for y in (-0.05, 0.05)])
    model = fit_link_spheres("plate", [plate], np.random.default_rng(0))
    check = check_spheres({"plate": [plate]}, {"plate": model}, np.random.default_rng(1))
    assert check.passed and len(model.radii) >= 2


def test_spheres_written_beside_a_robot_file_are_used_and_a_bad_one_is_refused(
    tmp_path: Path,
) -> None:
    robot = load_robot(str(write_test_arm(tmp_path)))
    path = write_spheres_beside(robot)
    assert path == tmp_path / "boxarm.spheres.json"
    spheres, origin = robot_spheres(robot)
    assert origin == "shipped" and spheres.urdf_sha256 == robot.urdf_sha256
    assert check_robot_spheres(robot, spheres, np.random.default_rng(2), 1000).passed
    data = json.loads(path.read_text())
    data["format"] = 0
    path.write_text(json.dumps(data))
    with pytest.raises(StalmError, match=r"boxarm\.spheres\.json: not a sphere file of format 1"):
        spheres_from_json(path)
    path.write_text(json.dumps({"links": 3}))
    with pytest.raises(StalmError, match="not a sphere file"):
        spheres_from_json(path)


def test_a_cache_that_cannot_be_written_is_a_warning(tmp_path: Path, monkeypatch) -> None:
    robot = load_robot(str(write_test_arm(tmp_path)))
    blocked = tmp_path / "cache-is-a-file"
    blocked.write_text("")
    monkeypatch.setenv("STALM_CACHE_DIR", str(blocked))
    with pytest.warns(StalmWarning, match="cannot cache boxarm's spheres"):
        _, origin = robot_spheres(robot)
    assert origin == "fitted"


def test_the_robots_page_states_the_shipped_sphere_counts() -> None:
    page = (Path(__file__).resolve().parents[2] / "docs" / "robots.md").read_text()
    rows = {
        cells[1].strip("` "): cells[7].strip()
        for cells in (line.split("|") for line in page.splitlines())
        if len(cells) > 8 and cells[1].strip().startswith("`")
    }
    assert {name: count.split()[0] for name, count in rows.items()} == {
        name: str(robot_spheres(load_robot(name))[0].total) for name in builtin_robots()
    }
