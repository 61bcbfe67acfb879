"""Mesh objects in the problem format and the simulator: the spec's checks (each error names
the field), a relative file found beside the problem, the outline's footprint and resting
height, the convex pieces (an OBJ's own groups, or V-HACD's, computed once and cached), the
physics check's mass and centre of mass, and the pictures drawing the mesh's triangles."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
import yaml

from stalm.errors import StalmError
from stalm.viz.view_data import scene_meshes
from stalm.world import mesh_pieces
from stalm.world import robot as robot_model
from stalm.world.grip_widths import hull_widths, narrowest_grip, too_wide
from stalm.world.mesh_files import mesh_outline, resolve_mesh_path
from stalm.world.object_spec import ObjectSpec
from stalm.world.physics_check import MESH_DENSITY_KG_M3, centre_of_mass, object_mass
from stalm.world.problem import load_problem
from stalm.world.problem_file import load_problem_file
from stalm.world.problem_record import PROBLEM_FOLDER_FIELD, problem_fields, record_problem
from stalm.world.scene import Sim

MESH1 = Path(__file__).resolve().parents[2] / "stalm" / "problems" / "mesh1.yaml"


def _box_obj(low: tuple[float, float, float], high: tuple[float, float, float], start: int) -> str:
    """One closed box as OBJ lines (vertices numbered from ``start``, 1-based)."""
    corners = [
        (x, y, z) for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])
    ]
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    lines = [f"v {x} {y} {z}" for x, y, z in corners]
    lines += ["f " + " ".join(str(start + i) for i in quad) for quad in quads]
    return "\n".join(lines) + "\n"


def _write_l_shape(path: Path, groups: bool) -> Path:
    """An L of two boxes (0.2 x 0.04 x 0.06 and 0.04 x 0.1 x 0.06, in mm-free units: metres):
    as two ``o`` groups (already convex pieces) or as one group (to be decomposed)."""
    first = _box_obj((0.0, 0.0, 0.0), (0.2, 0.04, 0.06), 1)
    second = _box_obj((0.0, 0.04, 0.0), (0.04, 0.14, 0.06), 9)
    if groups:
        path.write_text(f"o bar\n{first}o leg\n{second}")
    else:
        path.write_text(f"o l_shape\n{first}{second}")
    return path


def _problem_with(tmp_path: Path, **fields: object) -> Path:
    data = yaml.safe_load(MESH1.read_text())
    data["objects"][2].update(fields)
    path = tmp_path / "mesh.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"mesh": "missing.obj"}, r"objects\[2\]: mesh: mesh file 'missing.obj' not found"),
        ({"mesh": "pybullet_data:duck.dae"}, r"objects\[2\]: mesh: .*is not an OBJ file"),
        ({"mesh": "empty.obj"}, r"objects\[2\]: mesh: 'empty.obj' is an empty mesh"),
        ({"scale": 0.0}, r"objects\[2\]\.scale: .*greater than 0"),
        ({"scale": -1.0}, r"objects\[2\]\.scale: .*greater than 0"),
        ({"mesh": None}, r"objects\[2\]: a mesh needs 'mesh'"),
        ({"radius": 0.03}, r"objects\[2\]: a mesh takes 'mesh' and 'scale', not 'radius'"),
    ],
)
def test_a_bad_mesh_is_refused_naming_the_field(
    tmp_path: Path, fields: dict[str, object], message: str
) -> None:
    (tmp_path / "empty.obj").write_text("# nothing\nv 0 0 0\n")
    with pytest.raises(StalmError, match=message):
        load_problem_file(_problem_with(tmp_path, **fields))


def test_other_shapes_take_no_mesh_fields_and_dump_as_before() -> None:
    with pytest.raises(ValueError, match="a box takes no 'mesh' or 'scale'"):
        ObjectSpec.model_validate(
            {"name": "b", "shape": "box", "size": (0.1, 0.1, 0.1), "on": "r", "at": (0, 0)}
            | {"scale": 2.0}
        )
    can = ObjectSpec.model_validate(
        {"name": "c", "shape": "cylinder", "radius": 0.03, "height": 0.1, "on": "r", "at": (0, 0)}
    )
    assert "mesh" not in can.model_dump() and "scale" not in can.model_dump()


def test_a_relative_mesh_is_found_beside_the_problem_file_from_any_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _write_l_shape(tmp_path / "l.obj", groups=True)
    path = _problem_with(tmp_path, mesh="l.obj", scale=0.5, at=[0.05, 0.0])
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    obj = load_problem(path).spec.object("toy")
    assert obj.outline.path == tmp_path / "l.obj"
    # the L's bounding box, halved, centred on the object's frame with its bottom at z 0
    assert obj.half_extents == pytest.approx((0.05, 0.035, 0.015))
    assert obj.outline.points.min(axis=0) == pytest.approx((-0.05, -0.035, 0.0))


def test_a_relative_mesh_stays_found_for_another_robot_and_in_a_record(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--robot`` and a result record re-validate the problem away from its file: its
    relative mesh path still starts from the problem file's folder."""
    _write_l_shape(tmp_path / "l.obj", groups=True)
    path = _problem_with(tmp_path, mesh="l.obj", scale=0.5, at=[0.05, 0.0])
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    problem = load_problem(path)
    mesh = (tmp_path / "l.obj").resolve()
    assert problem.with_robot("xarm6").spec.object("toy").outline.path.resolve() == mesh
    record = json.loads(json.dumps(problem_fields(problem)))
    assert record[PROBLEM_FOLDER_FIELD] == str(tmp_path.resolve())
    reopened = record_problem(record, "mesh.json")
    assert reopened.spec.object("toy").outline.path.resolve() == mesh
    assert reopened.content_hash == problem.content_hash


def test_a_mesh_rests_on_its_region_inside_its_footprint() -> None:
    problem = load_problem(MESH1)
    with Sim(problem.spec) as sim:
        sim.set_state(problem.initial_state)
        for obj in problem.spec.objects:
            pose = problem.initial_state.pose(obj.name)
            low, high = p.getAABB(sim.bodies.objects[obj.name], physicsClientId=sim.client)
            hx, hy, hz = obj.half_extents
            c, s = abs(math.cos(pose.yaw)), abs(math.sin(pose.yaw))
            # PyBullet pads an AABB by a few mm; V-HACD's pieces reach a little past the mesh
            assert low[2] == pytest.approx(pose.z, abs=3e-3), obj.name
            assert high[2] == pytest.approx(pose.z + 2 * hz, abs=5e-3), obj.name
            assert low[0] == pytest.approx(pose.x - c * hx - s * hy, abs=5e-3), obj.name
            assert high[1] == pytest.approx(pose.y + s * hx + c * hy, abs=5e-3), obj.name


def test_an_objs_own_groups_are_its_pieces_and_one_group_is_decomposed_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("STALM_CACHE_DIR", str(tmp_path / "cache"))
    grouped = mesh_outline(_write_l_shape(tmp_path / "two.obj", groups=True), 1.0)
    pieces = mesh_pieces.convex_pieces(grouped)
    assert not pieces.decomposed and len(pieces.vertices) == 2
    assert pieces.collision_file == tmp_path / "two.obj"

    single = mesh_outline(_write_l_shape(tmp_path / "one.obj", groups=False), 1.0)
    assert len(single.vertices) == 1
    calls: list[Path] = []
    decompose = mesh_pieces._decompose

    def counted(source: Path, target: Path) -> None:
        calls.append(source)
        decompose(source, target)

    monkeypatch.setattr(mesh_pieces, "_decompose", counted)
    first = mesh_pieces.convex_pieces(single)
    assert first.decomposed and len(first.vertices) >= 2  # the L is concave: V-HACD splits it
    assert first.collision_file == mesh_pieces.decomposition_path(single)
    assert first.collision_file.parent == tmp_path / "cache" / "meshes"
    # the pieces cover the L: every vertex of the mesh lies in their bounding box
    everything = np.vstack(first.vertices)
    assert np.all(single.points[:, :2] >= everything.min(axis=0)[:2] - 1e-3)
    again = mesh_pieces.convex_pieces(mesh_outline(tmp_path / "one.obj", 2.0))  # other scale
    assert calls == [tmp_path / "one.obj"]  # the second load read the cache
    assert again.collision_file == first.collision_file
    assert len(again.vertices) == len(first.vertices)
    assert np.ptp(np.vstack(again.vertices), axis=0) == pytest.approx(
        2 * np.ptp(everything, axis=0), rel=1e-9
    )


def test_mesh_widths_are_the_support_width_of_its_hull() -> None:
    obj = load_problem(MESH1).spec.object("toy")
    points = obj.outline.points
    angles = np.linspace(0.0, math.pi, 7)
    widths = hull_widths(points, angles)
    for angle, width in zip(angles, widths, strict=True):
        along = points[:, 0] * math.cos(angle) + points[:, 1] * math.sin(angle)
        assert width == pytest.approx(along.max() - along.min(), abs=1e-12)
    # the toy is 0.033 x 0.092 in its frame: narrowest across x
    assert narrowest_grip(obj) == pytest.approx(2 * obj.half_extents[0], abs=2e-3)
    assert too_wide(obj, robot_model.GRIPPER_GAP) is None


def _mesh(path: str, scale: float = 1.0) -> ObjectSpec:
    fields = {"name": "m", "shape": "mesh", "mesh": path, "scale": scale, "on": "r", "at": (0, 0)}
    return ObjectSpec.model_validate(fields)


def test_a_mug_is_too_wide_for_the_gripper() -> None:
    mug = _mesh("pybullet_data:objects/mug.obj")
    reason = too_wide(mug, robot_model.GRIPPER_GAP)
    assert reason is not None
    assert reason.startswith("it is 0.0813 m across at its narrowest, wider than the gripper")


def test_a_meshs_mass_follows_its_volume_and_its_centre_its_shape(tmp_path: Path) -> None:
    obj = _mesh(str(_write_l_shape(tmp_path / "l.obj", groups=True)))
    volume = 0.2 * 0.04 * 0.06 + 0.04 * 0.1 * 0.06
    assert object_mass(obj) == pytest.approx(MESH_DENSITY_KG_M3 * volume, rel=1e-9)
    # the L's centroid in the OBJ's frame, moved into the object's (bbox centre, lifted)
    centroid = np.array([(0.008 * 0.1 + 0.004 * 0.02), (0.008 * 0.02 + 0.004 * 0.09), 0.0])
    centroid /= 0.012
    offset = np.array(mesh_pieces.object_pieces(obj).frame_position)
    expected = centroid + offset + np.array([0.0, 0.0, 0.03])
    assert centre_of_mass(obj) == pytest.approx(tuple(expected), abs=1e-9)


def test_the_pictures_draw_a_mesh_as_its_triangles() -> None:
    problem = load_problem(MESH1)
    toy = problem.spec.object("toy")
    with Sim(problem.spec) as sim:
        sim.set_state(problem.initial_state)
        meshes = scene_meshes(sim)
    moving = meshes["moving"]
    (rows,) = [b for b in meshes["bodies"] if b["name"] == "toy"]
    span = slice(rows["start"], rows["start"] + rows["count"])
    points = np.column_stack([moving["x"][span], moving["y"][span], moving["z"][span]])
    assert len(points) == len(toy.outline.points)
    hx, hy, hz = toy.half_extents
    assert points.min(axis=0) == pytest.approx((-hx, -hy, 0.0), abs=2e-3)
    assert points.max(axis=0) == pytest.approx((hx, hy, 2 * hz), abs=2e-3)


def test_pybullet_data_names_resolve_inside_the_package() -> None:
    import pybullet_data

    path = resolve_mesh_path("pybullet_data:duck_vhacd.obj", None)
    assert path == Path(pybullet_data.getDataPath()) / "duck_vhacd.obj"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", "a face names a vertex the file does not have"),
        ("v 0 0 0\n\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "is a flat mesh"),
        ("v 0 0 0\nv 1 0 x\nf 1 2 3\n", "is not a readable OBJ"),
    ],
)
def test_an_obj_that_is_no_mesh_is_refused(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        mesh_outline(path, 1.0)


def test_a_decomposition_that_writes_nothing_is_an_error_and_leaves_no_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("STALM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(mesh_pieces, "_VHACD_SCRIPT", "pass  # a V-HACD that writes nothing")
    single = mesh_outline(_write_l_shape(tmp_path / "one.obj", groups=False), 1.0)
    with pytest.raises(StalmError, match="V-HACD could not decompose the mesh"):
        mesh_pieces.convex_pieces(single)
    assert list((tmp_path / "cache" / "meshes").iterdir()) == []


def test_a_mesh_file_over_the_size_limit_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from stalm.world import mesh_files

    _write_l_shape(tmp_path / "l.obj", groups=True)
    monkeypatch.setattr(mesh_files, "MAX_OBJ_BYTES", 100)
    with pytest.raises(ValueError, match=r"mesh file 'l\.obj' is larger than 100 bytes"):
        resolve_mesh_path("l.obj", tmp_path)


def test_a_decomposition_is_cached_under_its_files_hash_and_resolution(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("STALM_CACHE_DIR", str(tmp_path / "cache"))
    single = mesh_outline(_write_l_shape(tmp_path / "one.obj", groups=False), 1.0)
    first = mesh_pieces.decomposition_path(single)
    assert first.name == f"{single.sha256[:32]}-vhacd{mesh_pieces.VHACD_RESOLUTION}.obj"
    monkeypatch.setattr(mesh_pieces, "VHACD_RESOLUTION", 2 * mesh_pieces.VHACD_RESOLUTION)
    assert mesh_pieces.decomposition_path(single) != first


def test_an_experiment_finds_a_mesh_beside_its_problem_file(tmp_path, monkeypatch) -> None:
    """A trial loads its problem from the file's text, in a folder of its own; a mesh path
    relative to the problem file still resolves against the problem file's folder."""
    import pybullet_data

    from stalm.experiments.suites import build_plan, trial_specs
    from stalm.experiments.trials import run_trial
    from stalm.world.problem import shipped_problems_dir

    source = Path(pybullet_data.getDataPath()) / "random_urdfs" / "258" / "258.obj"
    (tmp_path / "plate.obj").write_bytes(source.read_bytes())
    text = (shipped_problems_dir() / "mesh1.yaml").read_text()
    mine = tmp_path / "mine.yaml"
    mine.write_text(text.replace("pybullet_data:random_urdfs/258/258.obj", "plate.obj", 1))
    monkeypatch.chdir(Path(pybullet_data.getDataPath()))  # anywhere but the problem's folder
    plan = build_plan("table2", problems=(str(mine),), planners=("stalm-symbolic",), trials=1)
    spec = trial_specs(plan)[0]
    assert spec.problem_dir == str(tmp_path)
    record = run_trial(dataclasses.replace(spec, time_budget_s=1.0))
    assert "error" not in record, record.get("error")


def test_a_flat_piece_of_a_mesh_weighs_nothing_and_breaks_nothing(tmp_path) -> None:
    """An OBJ group may be a single face: its hull has no volume (Qhull refuses it), so it
    adds no mass, and the mass and centre of mass come from the pieces that have volume."""
    from stalm.world.mesh_pieces import hull_volume_centroid

    tetrahedron = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    triangle = np.array([[2, 2, 2], [3, 2, 2], [2, 3, 2]], dtype=float)
    assert hull_volume_centroid(triangle)[0] == 0.0
    volume, centre = hull_volume_centroid(tetrahedron)
    assert volume == pytest.approx(1 / 6) and centre == pytest.approx([0.25, 0.25, 0.25])
