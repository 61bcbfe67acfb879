"""Mesh objects a generated problem's clutter is drawn from, each fitted to a slot and resting
where it stands.

``stalm generate --objects-from SOURCE`` makes about half the clutter meshes (the rest stays
cans and bottles). ``SOURCE`` is a folder of Wavefront OBJ files (searched below it too) or
:data:`BUILTIN`, the set shipped here: procedural objects of ``pybullet_data``'s
``random_urdfs`` that passed the same checks when the set was made (a test checks them again).

Every mesh is scaled to fill one slot of the generator's grid (:func:`fitted_scale`: its
footprint's longer side :data:`SLOT_SIDE`, or its height :data:`TALLEST`), and is kept only if,
at that scale, it is at least :data:`LOWEST` tall and :data:`NARROWEST` wide (a flake is no
object to pick) and it rests where it is put: on a flat top, started upright and started
tipped 3 degrees toward each side, it comes back to lean at most 2 degrees and move at most
5 mm in 4 s (:func:`~stalm.world.stable_rest.why_it_does_not_rest`, with the centre of mass
of its convex pieces; a toy that only balances stands still when started upright, and falls
over in a scene). Of the 1,000 ``random_urdfs``, 492 topple, slide or only balance, 475 are
too low or too thin at a slot's scale and one cannot be read: 32 are kept
(:data:`BUILTIN_MESHES`; scanning the folder takes about 80 s). A mesh is never turned onto
another face here: a problem file stands an object on its file's own bottom.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stalm.errors import StalmError
from stalm.world.mesh_files import PYBULLET_DATA_PREFIX, mesh_outline, resolve_mesh_path

if TYPE_CHECKING:
    from stalm.world.problem import Problem

SLOT_SIDE = 0.07
"""The longer side of a clutter mesh's footprint (m): a bottle's diameter, so that it stands in
a slot as a bottle does, :data:`~stalm.generate.arrange.EDGE` from the next."""
TALLEST = 0.25
"""The tallest clutter mesh (m): a bottle's height."""
LOWEST = 0.03
"""A clutter mesh lower than this (m) at the scale that fits a slot is left out."""
NARROWEST = 0.02
"""A clutter mesh whose footprint's shorter side is below this (m) is left out."""
BUILTIN = "pybullet_data"
"""``--objects-from``'s name for the set shipped with stalm (:data:`BUILTIN_MESHES`)."""
MESH_SHARE = 0.5
"""The share of clutter objects drawn as meshes when the generator has some."""


@dataclass(frozen=True)
class ClutterMesh:
    """A mesh clutter is drawn from: its file as a problem file names it, and its scale."""

    mesh: str
    scale: float

    def kind(self) -> dict[str, Any]:
        """The object fields a problem file gives an object of this mesh."""
        return {"shape": "mesh", "mesh": self.mesh, "scale": self.scale}


@dataclass(frozen=True)
class ClutterSet:
    """The meshes kept from a source, and why each of the others was left out."""

    source: str
    meshes: tuple[ClutterMesh, ...]
    left_out: tuple[tuple[str, str], ...]
    """(file, reason) of each mesh left out."""

    def summary(self) -> str:
        """One line: how many were kept, and the reasons the others were not, most common
        first (ties in the order of the alphabet)."""
        seen = len(self.meshes) + len(self.left_out)
        counts = Counter(reason for _, reason in self.left_out)
        reasons = sorted(counts.items(), key=lambda item: (-item[1], item[0]))
        why = "; ".join(f"{count} {reason}" for reason, count in reasons)
        return f"--objects-from {self.source}: {len(self.meshes)} of {seen} meshes kept" + (
            f" ({why})" if why else ""
        )


def fitted_scale(path: Path) -> float:
    """The scale at which the OBJ at ``path`` fills a slot: the longer side of its footprint
    :data:`SLOT_SIDE`, or its height :data:`TALLEST`, whichever is reached first; rounded
    down to the places a generated file keeps (:func:`scale_places`), so that the file's object
    is the one checked."""
    hx, hy, hz = mesh_outline(path, 1.0).half_extents
    if min(max(hx, hy), hz) <= 0:
        raise ValueError(f"{path.name} is flat: it has no height or no footprint")
    scale = min(SLOT_SIDE / (2 * max(hx, hy)), TALLEST / (2 * hz))
    places = scale_places(scale)
    return math.floor(scale * 10**places) / 10**places


def scale_places(scale: float) -> int:
    """The decimal places a generated file keeps of a mesh's ``scale``: 4, as of every
    coordinate, and below 0.001 as many as keep 4 significant digits (a mesh drawn in
    millimetres is scaled by about 0.0005, which 4 places would cut by up to a fifth)."""
    if scale >= 1e-3 or scale <= 0:
        return 4
    return 3 - math.floor(math.log10(scale))


def why_left_out(mesh: ClutterMesh, base: Path | None = None) -> tuple[str, str] | None:
    """Why ``mesh`` cannot be clutter, as (a few words that group with others' reasons, the
    detail), or None when it can: at its scale it is too low or too thin, or it does not rest
    upright where it is put."""
    from stalm.world.stable_rest import why_it_does_not_rest  # PyBullet: only when checking

    problem = _alone_on_a_table(mesh, base)
    hx, hy, hz = problem.spec.objects[0].half_extents
    if 2 * hz < LOWEST:
        return f"lower than {LOWEST * 100:g} cm", f"{2 * hz * 100:.2g} cm tall"
    if 2 * min(hx, hy) < NARROWEST:
        return f"thinner than {NARROWEST * 100:g} cm", f"{2 * min(hx, hy) * 100:.2g} cm wide"
    falls = why_it_does_not_rest(problem, "thing")
    if falls is not None:
        return "topple, slide or only balance as loaded", falls
    return None


def _alone_on_a_table(mesh: ClutterMesh, base: Path | None) -> Problem:
    """A problem of ``mesh`` alone in the middle of a table, the robot well away."""
    from stalm.world.problem import Problem
    from stalm.world.problem_file import parse_problem

    data = {
        "name": "clutter_check",
        "horizon": 1,
        "time_budget_s": 1.0,
        "floor": [[-2.0, -2.0], [2.0, 2.0]],
        "robot": {"base": [-1.0, 0.0, 0.0]},
        "regions": [
            {
                "name": "table",
                "room": "room",
                "center": [1.0, 0.0],
                "size": [0.6, 0.6],
                "top": 0.7,
                "base_pose": [0.3, 0.0, 0.0],
            }
        ],
        "objects": [{"name": "thing", **mesh.kind(), "on": "table", "at": [0.0, 0.0]}],
        "goal": [["thing", "on", "table"]],
    }
    return Problem(parse_problem(data, f"<{mesh.mesh}>", base=base), f"<{mesh.mesh}>")


def clutter_from(
    source: str,
    problem_folder: Path,
    progress: Callable[[str], None] = lambda _: None,
) -> ClutterSet:
    """The meshes of ``source`` (:data:`BUILTIN`, or a folder of OBJ files) that can be
    clutter, named as a problem file in ``problem_folder`` names them (relative to it, or
    ``pybullet_data:`` inside that package). A folder holding no OBJ file, or none that can
    be clutter, is a StalmError that says why the files were left out."""
    if source == BUILTIN:
        return ClutterSet(source, BUILTIN_MESHES, ())
    folder = Path(source)
    if not folder.is_dir():
        raise StalmError(f"--objects-from {source}: not a folder (nor '{BUILTIN}')")
    files = sorted(p for p in folder.rglob("*") if p.suffix.lower() == ".obj" and p.is_file())
    if not files:
        raise StalmError(f"--objects-from {source}: no .obj file in the folder")
    kept: list[ClutterMesh] = []
    left_out: list[tuple[str, str]] = []
    first = ""
    for index, path in enumerate(files):
        progress(f"checking meshes for clutter: {path.name} ({index + 1} of {len(files)})")
        name = _problem_name(path, problem_folder)
        try:
            mesh = ClutterMesh(name, fitted_scale(resolve_mesh_path(name, problem_folder)))
            reason = why_left_out(mesh, problem_folder)
        except (StalmError, ValueError) as error:
            reason = _unreadable(error), str(error).splitlines()[0]
        if reason is None:
            kept.append(mesh)
        else:
            left_out.append((str(path), reason[0]))
            first = first or f"{path.name}: {reason[1]}"
    made = ClutterSet(source, tuple(kept), tuple(left_out))
    if not kept:
        raise StalmError(f"{made.summary()}: none can be clutter; the first: {first}")
    return made


def _unreadable(error: Exception) -> str:
    """A reason that groups with its kind: a mesh V-HACD failed on, or one unread."""
    return "V-HACD failed" if "V-HACD" in str(error) else "unreadable"


def _problem_name(path: Path, problem_folder: Path) -> str:
    """How a problem file in ``problem_folder`` names the mesh at ``path``."""
    import pybullet_data

    data = Path(pybullet_data.getDataPath()).resolve()
    if path.resolve().is_relative_to(data):
        return PYBULLET_DATA_PREFIX + path.resolve().relative_to(data).as_posix()
    # lexically, as a problem file's relative paths are resolved (a linked folder stays one)
    return Path(os.path.relpath(os.path.abspath(path), os.path.abspath(problem_folder))).as_posix()


BUILTIN_MESHES: tuple[ClutterMesh, ...] = (
    ClutterMesh("pybullet_data:random_urdfs/004/004.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/037/037.obj", 0.0113),
    ClutterMesh("pybullet_data:random_urdfs/053/053.obj", 0.0113),
    ClutterMesh("pybullet_data:random_urdfs/067/067.obj", 0.0113),
    ClutterMesh("pybullet_data:random_urdfs/095/095.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/197/197.obj", 0.0085),
    ClutterMesh("pybullet_data:random_urdfs/198/198.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/236/236.obj", 0.0085),
    ClutterMesh("pybullet_data:random_urdfs/246/246.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/250/250.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/341/341.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/345/345.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/347/347.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/355/355.obj", 0.0117),
    ClutterMesh("pybullet_data:random_urdfs/380/380.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/403/403.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/454/454.obj", 0.0167),
    ClutterMesh("pybullet_data:random_urdfs/459/459.obj", 0.0085),
    ClutterMesh("pybullet_data:random_urdfs/580/580.obj", 0.0113),
    ClutterMesh("pybullet_data:random_urdfs/615/615.obj", 0.0113),
    ClutterMesh("pybullet_data:random_urdfs/623/623.obj", 0.0113),
    ClutterMesh("pybullet_data:random_urdfs/628/628.obj", 0.0085),
    ClutterMesh("pybullet_data:random_urdfs/629/629.obj", 0.0113),
    ClutterMesh("pybullet_data:random_urdfs/656/656.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/666/666.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/695/695.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/703/703.obj", 0.017),
    ClutterMesh("pybullet_data:random_urdfs/745/745.obj", 0.0113),
    ClutterMesh("pybullet_data:random_urdfs/795/795.obj", 0.0112),
    ClutterMesh("pybullet_data:random_urdfs/847/847.obj", 0.0085),
    ClutterMesh("pybullet_data:random_urdfs/858/858.obj", 0.0115),
    ClutterMesh("pybullet_data:random_urdfs/918/918.obj", 0.0112),
)
"""The shipped clutter set: ``random_urdfs`` meshes that passed :func:`why_left_out` at
their :func:`fitted_scale` (every one of the 1,000 was checked; see the module docstring)."""
