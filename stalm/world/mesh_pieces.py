"""A mesh object's convex pieces: what PyBullet collides it as, computed once per file.

PyBullet collides a mesh on a moving body as the convex hull of each of its OBJ's ``o``
groups, so a concave mesh of one group (a mug, a brick with studs) would collide as one hull.
An OBJ of several groups is taken as its own decomposition; one of a single group is
decomposed with PyBullet's built-in V-HACD (``p.vhacd``, seconds per mesh), and the result is
kept in stalm's cache folder under the hash of the file's content (the decomposition is of the
file in its own units, so every scale of it shares one), so it is computed once.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from stalm import stopping
from stalm.cache_dir import stalm_cache_dir
from stalm.errors import StalmError
from stalm.world.mesh_files import MeshOutline, mesh_outline, read_obj
from stalm.world.object_spec import ObjectSpec

VHACD_RESOLUTION = 100_000
"""V-HACD's voxel count: a tenth of its default, which took 50 s and 83 pieces on the LEGO
brick on this project's machine; this takes 5 s and 42 (measured)."""
HULL_MARGIN = 0.001
"""PyBullet's collision margin around a convex hull (m): a hull resting exactly on a surface
reports this much penetration, the tolerance of "resting" (measured)."""
CACHE_FOLDER = "meshes"
"""The cache subfolder holding decomposed OBJs, ``<sha256>-vhacd<resolution>.obj``."""


@dataclass(frozen=True)
class MeshPieces:
    """A mesh's convex pieces: the OBJ PyBullet loads (one ``o`` group per piece), each piece's
    vertices scaled and in the object's frame, whether V-HACD made them, and how far they
    (and the drawn mesh) are lifted above the outline's frame so that they rest on the region
    rather than in it: V-HACD's hulls reach a little past the mesh, and every hull has
    :data:`HULL_MARGIN` around it."""

    collision_file: Path
    vertices: tuple[np.ndarray, ...]
    decomposed: bool
    lift: float
    frame_position: tuple[float, float, float]
    """Where the OBJ's (scaled) origin sits in the object's frame, lift included."""


def decomposition_path(outline: MeshOutline) -> Path:
    """Where the V-HACD decomposition of ``outline``'s file is cached."""
    name = f"{outline.sha256[:32]}-vhacd{VHACD_RESOLUTION}.obj"  # another resolution: another file
    return stalm_cache_dir() / CACHE_FOLDER / name


def convex_pieces(outline: MeshOutline) -> MeshPieces:
    """The convex pieces of the mesh ``outline`` (decomposing its file now if it has one
    piece and no cached decomposition)."""
    if len(outline.vertices) > 1:
        source, vertices, decomposed = outline.path, list(outline.vertices), False
    else:
        source, decomposed = decomposition_path(outline), True
        if not source.is_file():
            _decompose(outline.path, source)
        offset = np.asarray(outline.offset)
        vertices = [v * outline.scale + offset for v in read_obj(source).vertices]
    lowest = min(float(v[:, 2].min()) for v in vertices)
    lift = max(0.0, -lowest) + HULL_MARGIN
    up = np.array([0.0, 0.0, lift])
    x, y, z = outline.offset
    return MeshPieces(source, tuple(v + up for v in vertices), decomposed, lift, (x, y, z + lift))


def object_pieces(obj: ObjectSpec) -> MeshPieces:
    """The convex pieces of the mesh object ``obj`` (computed once per file and scale in a
    process, once per file on a machine)."""
    return _pieces(obj.outline.path, obj.outline.scale)


@cache
def _pieces(path: Path, scale: float) -> MeshPieces:
    return convex_pieces(mesh_outline(path, scale))


VHACD_TIMEOUT_S = 600.0
"""The longest a decomposition may take (the LEGO brick takes 5-13 s at this resolution)."""
_VHACD_SCRIPT = (
    "import sys, pybullet as p; "
    "p.vhacd(sys.argv[1], sys.argv[2], sys.argv[3], resolution=int(sys.argv[4]))"
)


def _decompose(source: Path, target: Path) -> None:
    """Write V-HACD's decomposition of ``source`` to ``target``. V-HACD prints its progress
    on the C library's stdout, which would corrupt a command's JSON output, so it runs in a
    child Python with its output discarded; it writes a temporary file in the same folder,
    so a run stopped halfway leaves no half-written decomposition."""
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(suffix=".obj", dir=target.parent)
    os.close(handle)
    log = temporary + ".log"
    try:
        arguments = [str(source), temporary, log, str(VHACD_RESOLUTION)]
        try:
            stopping.run_child(  # killed with this process, even by kill -9
                [sys.executable, "-c", _VHACD_SCRIPT, *arguments],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                timeout=VHACD_TIMEOUT_S,
            )
        except subprocess.TimeoutExpired:
            raise StalmError(
                f"V-HACD took over {VHACD_TIMEOUT_S:g} s to decompose the mesh {source}: give "
                "its convex pieces as the OBJ's own 'o' groups"
            ) from None
        try:
            read_obj.__wrapped__(Path(temporary))
        except ValueError:
            raise StalmError(f"V-HACD could not decompose the mesh {source}") from None
        os.replace(temporary, target)
    finally:
        for leftover in (temporary, log):
            if os.path.exists(leftover):
                os.remove(leftover)


def hull_volume_centroid(points: np.ndarray) -> tuple[float, np.ndarray]:
    """The volume (m^3) and centroid of the convex hull of ``points`` (n x 3): the hull's
    facets as tetrahedra with an interior point, summed. A flat piece (fewer than four points
    off one plane: an OBJ group may be a single face) has no volume and weighs nothing."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(points)
    except QhullError:
        return 0.0, points.mean(axis=0)
    inside = points[hull.vertices].mean(axis=0)
    corners = points[hull.simplices]  # facets x 3 x 3
    volumes = (
        np.abs(
            np.einsum(
                "ij,ij->i",
                corners[:, 0] - inside,
                np.cross(corners[:, 1] - inside, corners[:, 2] - inside),
            )
        )
        / 6.0
    )
    centroids = (corners.sum(axis=1) + inside) / 4.0
    total = float(volumes.sum())
    return total, (volumes[:, None] * centroids).sum(axis=0) / total


def pieces_volume_centroid(pieces: MeshPieces) -> tuple[float, tuple[float, float, float]]:
    """The summed volume and the centroid of a mesh's convex pieces' hulls (pieces that
    overlap count twice: a decomposition's pieces barely do)."""
    parts = [hull_volume_centroid(vertices) for vertices in pieces.vertices]
    volumes = np.array([volume for volume, _ in parts])
    total = float(volumes.sum())
    if total <= 0.0:
        raise StalmError(
            f"the mesh {pieces.collision_file} has no piece that spans a volume: it has no mass"
        )
    centre = (volumes[:, None] * np.array([centroid for _, centroid in parts])).sum(axis=0) / total
    return total, (float(centre[0]), float(centre[1]), float(centre[2]))
