"""Mesh objects' files: where an OBJ named in a problem file is, and what it holds.

A problem names a mesh object's file as a path relative to the problem file (or absolute), or
as ``pybullet_data:<path>`` inside the ``pybullet_data`` package that ships with PyBullet. The
file is a Wavefront OBJ: its vertices (``v``) and faces (``f``), split into pieces by its
object statements (``o``): PyBullet collides a moving mesh body as one convex hull per piece,
so an OBJ of several ``o`` groups is already a convex decomposition.

:class:`MeshOutline` is the mesh scaled and moved into the object's frame: origin at the
centre of the bottom face of its bounding box, so the object rests with the mesh's lowest point
on its region's top and its footprint is that box's rectangle, as a box object's is.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

PYBULLET_DATA_PREFIX = "pybullet_data:"
"""How a problem file names a mesh inside the ``pybullet_data`` package."""
MAX_OBJ_BYTES = 50_000_000
"""The largest OBJ file read (bytes): a mesh object is a graspable thing, not a scanned room."""


def resolve_mesh_path(name: str, base: Path | None) -> Path:
    """The file a problem's ``mesh`` field names: ``pybullet_data:<path>`` inside that
    package, an absolute path as is, a relative one against ``base`` (the problem file's
    folder; the working folder if None). A ValueError says what is wrong with it."""
    if name.startswith(PYBULLET_DATA_PREFIX):
        import pybullet_data

        path = Path(pybullet_data.getDataPath()) / name[len(PYBULLET_DATA_PREFIX) :]
    else:
        path = Path(name)
        if not path.is_absolute() and base is not None:
            # lexically, so that "../meshes/a.obj" resolves for a folder not made yet
            path = Path(os.path.normpath(base / path))
    if path.suffix.lower() != ".obj":
        raise ValueError(f"'{name}' is not an OBJ file (a mesh is a Wavefront .obj)")
    if not path.is_file():
        raise ValueError(f"mesh file '{name}' not found (looked for {path})")
    if path.stat().st_size > MAX_OBJ_BYTES:
        raise ValueError(f"mesh file '{name}' is larger than {MAX_OBJ_BYTES} bytes")
    return path


@dataclass(frozen=True)
class ObjPieces:
    """An OBJ's pieces as written (its own units and frame): the vertices and triangles of
    each ``o`` group that has faces, and the file's content hash."""

    vertices: tuple[np.ndarray, ...]
    triangles: tuple[np.ndarray, ...]
    sha256: str


def _parse_obj(text: str) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(vertices, triangles) per ``o`` group; face indices are the file's (1-based, global,
    negative counting back), triangles fan out from a face's first corner."""
    vertices: list[tuple[float, float, float]] = []
    groups: list[list[tuple[int, int, int]]] = [[]]
    for line in text.splitlines():
        words = line.split()
        if not words:
            continue
        if words[0] == "v" and len(words) >= 4:
            vertices.append((float(words[1]), float(words[2]), float(words[3])))
        elif words[0] == "o":
            if groups[-1]:
                groups.append([])
        elif words[0] == "f" and len(words) >= 4:
            corners = []
            for word in words[1:]:
                index = int(word.split("/")[0])
                corners.append(index - 1 if index > 0 else len(vertices) + index)
            for k in range(1, len(corners) - 1):
                groups[-1].append((corners[0], corners[k], corners[k + 1]))
    points = np.asarray(vertices, dtype=float).reshape(-1, 3)
    piece_vertices, piece_triangles = [], []
    for faces in groups:
        if not faces:
            continue
        triangles = np.asarray(faces, dtype=np.int64)
        if triangles.min() < 0 or triangles.max() >= len(points):
            raise ValueError("a face names a vertex the file does not have")
        used, local = np.unique(triangles, return_inverse=True)
        piece_vertices.append(points[used])
        piece_triangles.append(local.reshape(-1, 3))
    return piece_vertices, piece_triangles


@cache
def read_obj(path: Path) -> ObjPieces:
    """The pieces of the OBJ at ``path``; a ValueError if it is no mesh (unreadable, not an
    OBJ's text, no faces, or the faces span no volume)."""
    data = path.read_bytes()
    try:
        vertices, triangles = _parse_obj(data.decode("utf-8", errors="replace"))
    except ValueError as error:
        raise ValueError(f"'{path.name}' is not a readable OBJ ({error})") from None
    if not vertices:
        raise ValueError(f"'{path.name}' is an empty mesh: it has no faces")
    extent = np.ptp(np.vstack(vertices), axis=0)
    if not np.all(extent > 0):
        raise ValueError(f"'{path.name}' is a flat mesh: it spans no volume")
    return ObjPieces(tuple(vertices), tuple(triangles), hashlib.sha256(data).hexdigest())


@dataclass(frozen=True)
class MeshOutline:
    """A mesh as an object of the scene: its pieces' vertices scaled and in the object's frame
    (origin at the bottom centre of their bounding box), the offset that moves the OBJ's frame
    (scaled) there, and the half extents of that box."""

    path: Path
    scale: float
    vertices: tuple[np.ndarray, ...]
    triangles: tuple[np.ndarray, ...]
    offset: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    sha256: str

    @property
    def points(self) -> np.ndarray:
        """Every vertex (n x 3), in the object's frame."""
        return np.vstack(self.vertices)


@cache
def mesh_outline(path: Path, scale: float) -> MeshOutline:
    """The OBJ at ``path`` scaled by ``scale`` in the object's frame (see :class:`MeshOutline`)."""
    pieces = read_obj(path)
    scaled = [v * scale for v in pieces.vertices]
    everything = np.vstack(scaled)
    low, high = everything.min(axis=0), everything.max(axis=0)
    offset = np.array([-(low[0] + high[0]) / 2, -(low[1] + high[1]) / 2, -low[2]])
    half = (high - low) / 2
    return MeshOutline(
        path,
        scale,
        tuple(v + offset for v in scaled),
        pieces.triangles,
        (float(offset[0]), float(offset[1]), float(offset[2])),
        (float(half[0]), float(half[1]), float(half[2])),
        pieces.sha256,
    )
