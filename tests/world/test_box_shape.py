"""Box objects in the problem format and the simulator: the spec's checks (each error names
the field), the PyBullet body (its AABB where the spec puts it), the gripper's opening (the
figure every grasp derives from, measured against the Panda's fingers) and the warning that
an object no grasp fits can never move."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
import yaml

from stalm.errors import StalmError
from stalm.viz.render import top_down
from stalm.viz.view_data import scene_meshes
from stalm.world import robot as robot_model
from stalm.world.grip_widths import narrowest_grip, too_wide
from stalm.world.object_spec import ObjectSpec
from stalm.world.physics_check import centre_of_mass
from stalm.world.problem import load_problem
from stalm.world.problem_file import load_problem_file
from stalm.world.scene import Sim
from stalm.world.spec import footprints_overlap
from tests.cli_runner import run_cli

BOX1 = Path(__file__).resolve().parents[2] / "stalm" / "problems" / "box1.yaml"


def _data() -> dict[str, object]:
    return yaml.safe_load(BOX1.read_text())


def _box(**fields: object) -> ObjectSpec:
    base: dict[str, object] = {"name": "b", "shape": "box", "on": "r", "at": (0.0, 0.0)}
    return ObjectSpec.model_validate({**base, **fields})


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda o: o.pop("size"), r"objects\[0\]: a box needs 'size' \(x, y, z\)"),
        (lambda o: o.update(radius=0.03), r"objects\[0\]: a box takes 'size'.*not 'radius'"),
        (lambda o: o.update(height=0.1), r"objects\[0\]: a box takes 'size'.*'height'"),
        (lambda o: o.update(size=[0.05, -0.1, 0.2]), r"objects\[0\]\.size\[1\]: .*greater than 0"),
        (lambda o: o.update(size=[0.05, 0.1]), r"objects\[0\]\.size"),
        (lambda o: o.update(handle_height=0.1), r"objects\[0\]: a box has no handles"),
        (
            lambda o: o.update(at=[0.18, 0.0]),
            r"objects\[0\]\.at: .*outside the usable area .*its footprint is 0.12 x 0.05 m",
        ),
        (lambda o: o.update(at=[0.1, 0.0], yaw=0.0), r"objects\[1\]\.at: 'cereal' overlaps"),
    ],
)
def test_a_bad_box_is_refused_naming_the_field(
    tmp_path: Path, mutate: object, message: str
) -> None:
    data = _data()
    mutate(data["objects"][0])  # type: ignore[index,operator]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(StalmError, match=message):
        load_problem_file(path)


def test_a_box_is_its_size_and_its_footprint_a_turned_rectangle() -> None:
    box = _box(size=(0.3, 0.07, 0.14))
    assert box.half_extents == (0.15, 0.035, 0.07)
    assert centre_of_mass(box) == (0.0, 0.0, 0.07)
    assert narrowest_grip(box) == pytest.approx(0.07)
    can = ObjectSpec.model_validate(
        {"name": "c", "shape": "cylinder", "radius": 0.033, "height": 0.12, "on": "r", "at": (0, 0)}
    )
    # the can 0.1 m to the side of the box's centre: clear of it square, inside it turned 90 deg
    assert not footprints_overlap(box, (0.0, 0.0, 0.0), can, (0.0, 0.1, 0.0))
    assert footprints_overlap(box, (0.0, 0.0, math.pi / 2), can, (0.0, 0.1, 0.0))


def test_the_box_body_in_pybullet_has_the_specs_extent_where_it_stands() -> None:
    problem = load_problem(BOX1)
    with Sim(problem.spec) as sim:
        sim.set_state(problem.initial_state)
        for obj in problem.spec.objects:
            if obj.shape != "box":
                continue
            pose = problem.initial_state.pose(obj.name)
            low, high = p.getAABB(sim.bodies.objects[obj.name], physicsClientId=sim.client)
            hx, hy, hz = obj.half_extents
            c, s = abs(math.cos(pose.yaw)), abs(math.sin(pose.yaw))
            expected_low = (pose.x - c * hx - s * hy, pose.y - s * hx - c * hy, pose.z)
            expected_high = (pose.x + c * hx + s * hy, pose.y + s * hx + c * hy, pose.z + 2 * hz)
            # PyBullet pads an AABB by its collision margin (a few mm at most)
            assert low == pytest.approx(expected_low, abs=5e-3), obj.name
            assert high == pytest.approx(expected_high, abs=5e-3), obj.name


def test_the_gripper_gap_is_the_pandas_fully_open_finger_gap() -> None:
    problem = load_problem(BOX1)
    with Sim(problem.spec) as sim:
        arm, c = sim.bodies.arm, sim.client
        for joint in range(p.getNumJoints(arm, physicsClientId=c)):
            name = p.getJointInfo(arm, joint, physicsClientId=c)[1].decode()
            if name.startswith("panda_finger_joint"):
                p.resetJointState(arm, joint, robot_model.FINGER_OPENING, physicsClientId=c)
        names = {
            p.getJointInfo(arm, j, physicsClientId=c)[12].decode(): j
            for j in range(p.getNumJoints(arm, physicsClientId=c))
        }
        points = p.getClosestPoints(
            arm,
            arm,
            1.0,
            linkIndexA=names["panda_leftfinger"],
            linkIndexB=names["panda_rightfinger"],
            physicsClientId=c,
        )
    gap = min(point[8] for point in points)
    assert gap == pytest.approx(robot_model.GRIPPER_GAP, abs=5e-4)


def test_an_object_no_grasp_fits_loads_with_a_warning_that_it_can_never_move(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _data()
    data["objects"][2]["size"] = [0.3, 0.09, 0.14]  # type: ignore[index]
    path = tmp_path / "wide.yaml"
    path.write_text(yaml.safe_dump(data))
    crate = load_problem(path).spec.object("crate")
    assert too_wide(crate, robot_model.GRIPPER_GAP) == (
        "it is 0.09 m across at its narrowest, wider than the gripper opens (0.0778 m): "
        "no grasp fits it"
    )
    assert run_cli(monkeypatch, "problems", "--file", str(path)) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "'crate' can never be moved (the goal names it): it is 0.09 m across" in err


def test_the_pictures_draw_a_box_as_its_eight_corners_and_its_colour() -> None:
    problem = load_problem(BOX1)
    crate = problem.spec.object("crate")
    with Sim(problem.spec) as sim:
        sim.set_state(problem.initial_state)
        meshes = scene_meshes(sim)
        top = np.asarray(top_down(sim, 320, 320))[:, :, :3].astype(int)
    moving = meshes["moving"]
    (rows,) = [b for b in meshes["bodies"] if b["name"] == "crate"]
    span = slice(rows["start"], rows["start"] + rows["count"])
    corners = np.column_stack([moving["x"][span], moving["y"][span], moving["z"][span]])
    assert len(corners) == 8
    assert corners.min(axis=0) == pytest.approx((-0.15, -0.035, 0.0), abs=1e-4)
    assert corners.max(axis=0) == pytest.approx((0.15, 0.035, 0.14), abs=1e-4)
    # seen from above, the crate's colour (lit, so within a margin) covers a patch of pixels
    colour = np.array(crate.color[:3]) * 255
    near = np.abs(top - colour).max(axis=2) < 40
    assert near.sum() > 20
