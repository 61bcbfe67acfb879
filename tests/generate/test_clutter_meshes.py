"""Mesh clutter: a folder's meshes fitted to a slot and kept only if they rest upright; the
shipped set passes the same checks; generated scenes with mesh clutter rest where the file puts
them, are the same for the same seed, and their meshes are covered conservatively by the
batched engine's boxes."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import numpy as np
import pybullet_data
import pytest
import yaml

from stalm.errors import StalmError
from stalm.generate.arrange import Knobs
from stalm.generate.clutter_meshes import (
    BUILTIN,
    BUILTIN_MESHES,
    LOWEST,
    NARROWEST,
    SLOT_SIDE,
    TALLEST,
    ClutterMesh,
    _alone_on_a_table,
    clutter_from,
    fitted_scale,
    why_left_out,
)
from stalm.generate.problem_maker import generate_problem
from stalm.generate.suite import generate_suite
from stalm.motion.scene_primitives import MESH_BOX_PADDING, MOST_PIECE_BOXES, object_boxes
from stalm.world.mesh_files import resolve_mesh_path
from stalm.world.mesh_pieces import object_pieces
from stalm.world.physics_check import unsettled_objects
from stalm.world.stable_rest import why_it_does_not_rest
from tests.cli_runner import run_cli

RANDOM_URDFS = Path(pybullet_data.getDataPath()) / "random_urdfs"
KEPT, TOPPLES, LOW, THIN = "004", "003", "000", "006"
"""random_urdfs that rest upright at a slot's scale, that topple as loaded, that are lower
than 3 cm at it, and thinner than 2 cm (found by scanning the 1,000)."""


def _folder(tmp_path: Path, *numbers: str) -> Path:
    folder = tmp_path / "meshes"
    (folder / "deeper").mkdir(parents=True)
    for index, number in enumerate(numbers):
        into = folder / "deeper" if index % 2 else folder
        shutil.copy(RANDOM_URDFS / number / f"{number}.obj", into / f"{number}.obj")
    return folder


def test_a_folder_keeps_what_rests_upright_and_says_why_the_rest_was_left_out(
    tmp_path: Path,
) -> None:
    folder = _folder(tmp_path, KEPT, TOPPLES, LOW, THIN)
    (folder / "broken.obj").write_text("v 0 0 0\n")  # no face: unreadable
    (folder / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")  # no height
    (folder / "notes.txt").write_text("not a mesh")
    made = clutter_from(str(folder), tmp_path / "problems")
    assert [m.mesh for m in made.meshes] == [f"../meshes/{KEPT}.obj"]  # relative to the file
    assert made.meshes[0].scale == fitted_scale(folder / f"{KEPT}.obj")
    assert made.summary() == (
        f"--objects-from {folder}: 1 of 6 meshes kept "
        "(2 unreadable; 1 lower than 3 cm; 1 thinner than 2 cm; "
        "1 topple, slide or only balance as loaded)"
    )


def test_a_folder_inside_pybullet_data_is_named_as_the_package_names_it(tmp_path: Path) -> None:
    made = clutter_from(str(RANDOM_URDFS / KEPT), tmp_path)
    assert made.meshes == (
        ClutterMesh(f"pybullet_data:random_urdfs/{KEPT}/{KEPT}.obj", made.meshes[0].scale),
    )


def test_a_folder_with_nothing_to_keep_is_an_error_naming_why(tmp_path: Path) -> None:
    folder = _folder(tmp_path, TOPPLES)
    (folder / "broken.obj").write_text("v 0 0 0\n")
    with pytest.raises(
        StalmError,
        match=r"0 of 2 meshes kept .*clutter; the first: 003\.obj: started upright, it leaned",
    ):
        clutter_from(str(folder), tmp_path)
    with pytest.raises(StalmError, match=r"no \.obj file in the folder"):
        clutter_from(str(tmp_path / "meshes" / "deeper"), tmp_path)
    with pytest.raises(StalmError, match=r"not a folder \(nor 'pybullet_data'\)"):
        clutter_from(str(tmp_path / "nowhere"), tmp_path)


def test_a_linked_output_folder_names_meshes_as_a_problem_file_there_finds_them(
    tmp_path: Path,
) -> None:
    """Names are made lexically, as the file's relative paths are read: an output folder that
    is a link to elsewhere still finds meshes named from where the link stands."""
    folder = _folder(tmp_path, KEPT)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "out").symlink_to(elsewhere)
    made = clutter_from(str(folder), tmp_path / "out")
    assert made.meshes[0].mesh == f"../meshes/{KEPT}.obj"
    assert resolve_mesh_path(made.meshes[0].mesh, tmp_path / "out") == folder / f"{KEPT}.obj"


def test_a_mesh_drawn_in_millimetres_keeps_four_significant_digits_of_its_scale(
    tmp_path: Path,
) -> None:
    source = (RANDOM_URDFS / KEPT / f"{KEPT}.obj").read_text().splitlines()
    scaled = [
        "v " + " ".join(f"{float(x) * 1000:.6f}" for x in line.split()[1:4])
        if line.startswith("v ")
        else line
        for line in source
    ]
    (tmp_path / "mm.obj").write_text("\n".join(scaled) + "\n")
    scale = fitted_scale(tmp_path / "mm.obj")
    assert 1e-6 < scale < 1e-4 and float(f"{scale:.4g}") == scale != float(f"{scale:.3g}")
    metres = fitted_scale(RANDOM_URDFS / KEPT / f"{KEPT}.obj")
    assert scale == pytest.approx(metres / 1000, rel=1e-2)
    knobs = Knobs(objects=14, clutter=(ClutterMesh("mm.obj", scale),))
    made = generate_problem(knobs, 1, "mm", layout="storeroom", folder=tmp_path)
    assert f"scale: {scale}\n" in made.text  # the file keeps the scale that was checked


def test_a_fitted_mesh_fills_one_slot() -> None:
    for number in (KEPT, TOPPLES, LOW, "444"):
        mesh = ClutterMesh(f"pybullet_data:random_urdfs/{number}/{number}.obj", 0.0)
        path = resolve_mesh_path(mesh.mesh, None)
        scale = fitted_scale(path)
        problem_mesh = ClutterMesh(mesh.mesh, scale)
        hx, hy, hz = _half_extents(problem_mesh)
        # the scale is rounded down to 4 places: a side falls short by at most 1e-4 of itself
        # at scale 1
        tol = 1e-4 * 2 * max(_half_extents(ClutterMesh(mesh.mesh, 1.0)))
        assert max(hx, hy) * 2 <= SLOT_SIDE + 1e-9 and hz * 2 <= TALLEST + 1e-9
        assert max(hx, hy) * 2 >= SLOT_SIDE - tol or hz * 2 >= TALLEST - tol


def _half_extents(mesh: ClutterMesh) -> tuple[float, float, float]:
    from stalm.world.mesh_files import mesh_outline

    return mesh_outline(resolve_mesh_path(mesh.mesh, None), mesh.scale).half_extents


@pytest.mark.parametrize(
    "meshes",
    [
        pytest.param(BUILTIN_MESHES[::8], id="a sample"),
        pytest.param(BUILTIN_MESHES, id="all", marks=pytest.mark.slow),
    ],
)
def test_the_shipped_set_passes_the_checks_it_was_made_by(
    meshes: tuple[ClutterMesh, ...],
) -> None:
    assert len(BUILTIN_MESHES) == 32 and clutter_from(BUILTIN, Path(".")).meshes == BUILTIN_MESHES
    for mesh in meshes:
        assert mesh.scale == fitted_scale(resolve_mesh_path(mesh.mesh, None)), mesh
        assert why_left_out(mesh) is None, mesh
        hx, hy, hz = _half_extents(mesh)
        assert 2 * hz >= LOWEST and 2 * min(hx, hy) >= NARROWEST


def test_a_mesh_that_only_balances_is_found_by_tipping_it() -> None:
    """``random_urdfs/792`` stands still for 8 s started upright, and fell over in a generated
    scene within 1 s; tipped 3 degrees it falls at once. ``004`` leans 0.8 degree and stays."""
    balancing = ClutterMesh("pybullet_data:random_urdfs/792/792.obj", 0.0112)
    problem = _alone_on_a_table(balancing, None)
    assert unsettled_objects(problem, settle_seconds=8.0) == ()  # upright, it stands
    reason = why_it_does_not_rest(problem, "thing")
    assert reason is not None and reason.startswith("started tipped 3 deg, it leaned")
    resting = ClutterMesh(f"pybullet_data:random_urdfs/{KEPT}/{KEPT}.obj", 0.0112)
    assert why_it_does_not_rest(_alone_on_a_table(resting, None), "thing") is None


@pytest.mark.slow
def test_a_scene_where_clutter_falls_is_dropped_for_the_next_candidate() -> None:
    """Meshes that only balance, as clutter: the candidates whose settled scene has one
    fallen are dropped, and the error after the last names one that did not rest."""
    balancing = (ClutterMesh("pybullet_data:random_urdfs/792/792.obj", 0.0112),)
    with pytest.raises(StalmError, match=r"item_\d+ does not rest where it stands \(moved"):
        generate_problem(Knobs(objects=60, clutter=balancing), 0, "falls", layout="storeroom")


def test_a_generated_scene_of_mesh_clutter_rests_and_is_the_same_for_the_same_seed() -> None:
    knobs = Knobs(objects=40, clutter=BUILTIN_MESHES)
    first = generate_problem(knobs, 3, "meshy", layout="storeroom")
    again = generate_problem(knobs, 3, "meshy", layout="storeroom")
    assert first.text == again.text
    objects = yaml.safe_load(first.text)["objects"]
    clutter = [o for o in objects if o["name"].startswith("item_")]
    meshes = [o for o in clutter if o["shape"] == "mesh"]
    assert 0.3 <= len(meshes) / len(clutter) <= 0.7  # about half, drawn
    assert {(o["mesh"], o["scale"]) for o in meshes} <= {(m.mesh, m.scale) for m in BUILTIN_MESHES}
    assert unsettled_objects(first.problem) == ()  # every object rests where the file puts it


PLAIN_HASHES = {
    "kitchen": "ef86702b24b57717ad70cdd63647b1f0e6fd2604bd754774906af7e02fa70dee",
    "storeroom": "d30d822c698b896ca673982736843f528fce681930b5d359c04e1796e167cd16",
    "index": "824e44530ac67a9d22fcb2ebf59eb08d54cb9eaacbc9f0d7192ac34259c4451e",
}
"""SHA-256 of files made before mesh clutter existed (at ``0f023a1``): a kitchen-hall problem
(12 objects, seed 0), a storeroom one (30 objects, seed 4) and a storeroom suite's index (one
problem of 12, seed 0)."""


def test_without_meshes_a_scene_is_made_as_before_mesh_clutter_existed(tmp_path: Path) -> None:
    """The mesh draw is skipped when there are no meshes, the scene is not settled and the
    index has no clutter: every earlier seed makes the same file, byte for byte."""
    kitchen = generate_problem(Knobs(objects=12), 0, "plain").text
    storeroom = generate_problem(Knobs(objects=30), 4, "plain", layout="storeroom").text
    generate_suite("plain", (12,), 1, 0, tmp_path, Knobs(objects=12), layout="storeroom")
    index = (tmp_path / "index.json").read_text()
    made = {"kitchen": kitchen, "storeroom": storeroom, "index": index}
    assert {k: hashlib.sha256(v.encode()).hexdigest() for k, v in made.items()} == PLAIN_HASHES


def test_a_suite_records_its_clutter_and_a_plain_suite_its_old_index(tmp_path: Path) -> None:
    knobs = Knobs(objects=12, clutter=BUILTIN_MESHES[:3])
    meshy = generate_suite("meshy", (12,), 1, 0, tmp_path / "meshy", knobs, layout="storeroom")
    index = yaml.safe_load((tmp_path / "meshy" / "index.json").read_text())
    assert index["knobs"]["clutter"] == [{"mesh": m.mesh, "scale": m.scale} for m in knobs.clutter]
    assert meshy.knobs["clutter"] == index["knobs"]["clutter"]
    plain = generate_suite("plain", (12,), 1, 0, tmp_path / "plain", Knobs(objects=12))
    assert "clutter" not in plain.knobs
    # the same arguments resume the suite rather than refuse it as another
    again = generate_suite("meshy", (12,), 1, 0, tmp_path / "meshy", knobs, layout="storeroom")
    assert again.problems == meshy.problems


def test_the_command_says_what_it_kept_and_writes_meshes_relative_to_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _folder(tmp_path, KEPT, TOPPLES)
    out = tmp_path / "made" / "scene.yaml"
    code = run_cli(
        monkeypatch, "generate", "--layout", "storeroom", "--objects", "30", "--seed", "2",
        "--objects-from", str(folder), "-o", str(out),
    )  # fmt: skip
    assert code == 0
    said = capsys.readouterr().err
    assert "1 of 2 meshes kept (1 topple, slide or only balance as loaded)" in said
    assert f"mesh: ../meshes/{KEPT}.obj" in out.read_text()
    bad = run_cli(monkeypatch, "generate", "--objects-from", str(tmp_path / "none"), "-o", str(out))
    assert bad == 2 and "not a folder" in capsys.readouterr().err


def test_a_mesh_of_many_pieces_is_covered_by_one_box_that_holds_every_piece() -> None:
    problem_objects = _objects_of("meshclutter20_seed5")
    many = [o for o in problem_objects if o.shape == "mesh" and len(object_pieces(o).vertices) > 8]
    few = [o for o in problem_objects if o.shape == "mesh" and len(object_pieces(o).vertices) <= 8]
    assert many and few
    for obj in many + few:
        boxes = object_boxes(obj)
        pieces = object_pieces(obj).vertices
        assert len(boxes) == (1 if len(pieces) > MOST_PIECE_BOXES else len(pieces))
        points = np.vstack(pieces)
        inside = np.zeros(len(points), dtype=bool)
        for centre, half in boxes:
            margin = np.asarray(half) - np.abs(points - np.asarray(centre))
            inside |= np.all(margin >= MESH_BOX_PADDING - 1e-12, axis=1)
        assert inside.all(), obj.name  # with the padding to spare: a conservative cover


def _objects_of(name: str):  # type: ignore[no-untyped-def]
    from stalm.world.problem import load_problem

    data = Path(__file__).parents[1] / "motion" / "data" / f"{name}.yaml"
    return load_problem(data).spec.objects
