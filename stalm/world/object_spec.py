"""A movable object's spec: its shape and size, where it starts, and the checks that a shape
is given the dimensions it needs (:class:`ObjectSpec`); the problem that holds it is
:mod:`stalm.world.spec`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import (
    Field,
    PrivateAttr,
    SerializerFunctionWrapHandler,
    ValidationInfo,
    model_serializer,
    model_validator,
)

from stalm.world.mesh_files import MeshOutline, mesh_outline, resolve_mesh_path
from stalm.world.spec_values import RGBA, Coordinate, Name, Positive, SpecModel, Vec2

ShapeName = Literal["cylinder", "disc", "grill", "box", "mesh"]

MESH_BASE_CONTEXT = "mesh_base"
"""The validation context key holding the folder a problem's relative ``mesh`` paths resolve
against (the problem file's)."""


class ObjectSpec(SpecModel):
    """A movable object: a primitive shape resting on a region at the start.

    ``cylinder``: cans, salters, bottles (radius, height). ``disc``: a plate (radius, height
    is its thickness). ``grill``: a box body (``size``, its lid included) with two side
    handles along its y axis at ``handle_height`` above its bottom, grasped at a handle.
    ``box``: a cuboid of full extents ``size``. ``mesh``: the OBJ file ``mesh`` (relative to
    the problem file, or ``pybullet_data:<path>``) scaled by ``scale``, resting with its lowest
    point on the region; its footprint is its bounding rectangle (:mod:`~stalm.world.mesh_files`).
    """

    name: Name
    shape: ShapeName
    radius: Positive | None = None
    height: Positive | None = None
    size: tuple[Positive, Positive, Positive] | None = None
    handle_height: Positive | None = Field(
        default=None,
        description="a grill's handles' height above its bottom (m); 3/4 of its height if unset",
    )
    on: str
    at: Vec2 = Field(description="start position (u, v) in the region's frame")
    yaw: Coordinate = Field(default=0.0, description="start yaw relative to the region's frame")
    color: RGBA = (0.8, 0.2, 0.2, 1.0)
    mesh: str | None = Field(default=None, description="a mesh object's OBJ file")
    scale: Positive | None = Field(default=None, description="a mesh's scale (1 if unset)")
    _mesh_path: Path | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _mesh_file_is_a_mesh(self, info: ValidationInfo) -> ObjectSpec:
        """A mesh object's file is found and read now, so a missing or empty one is refused
        with the problem, naming the field."""
        if self.shape != "mesh":
            if self.mesh is not None or self.scale is not None:
                raise ValueError(f"a {self.shape} takes no 'mesh' or 'scale': they are a mesh's")
            return self
        if self.mesh is None:
            raise ValueError("a mesh needs 'mesh': its OBJ file")
        if self.radius is not None or self.height is not None or self.size is not None:
            raise ValueError("a mesh takes 'mesh' and 'scale', not 'radius', 'height' or 'size'")
        context = info.context if isinstance(info.context, dict) else {}
        base = context.get(MESH_BASE_CONTEXT)
        try:
            path = resolve_mesh_path(self.mesh, Path(base) if base is not None else None)
            mesh_outline(path, self.mesh_scale)  # reads it: an empty or unreadable one fails
        except ValueError as error:
            raise ValueError(f"mesh: {error}") from None
        self._mesh_path = path
        return self

    @property
    def mesh_scale(self) -> float:
        """A mesh's scale: ``scale``, 1 if unset."""
        return self.scale if self.scale is not None else 1.0

    @property
    def outline(self) -> MeshOutline:
        """A mesh object's vertices in its frame (:class:`~stalm.world.mesh_files.MeshOutline`)."""
        assert self._mesh_path is not None, "a mesh object's file is resolved when validated"
        return mesh_outline(self._mesh_path, self.mesh_scale)

    @model_validator(mode="after")
    def _dimensions_match_shape(self) -> ObjectSpec:
        if self.shape == "mesh":
            pass
        elif self.shape in ("cylinder", "disc"):
            if self.radius is None or self.height is None:
                raise ValueError(f"a {self.shape} needs 'radius' and 'height'")
            if self.size is not None:
                raise ValueError(f"a {self.shape} takes 'radius' and 'height', not 'size'")
        elif self.shape == "box":
            if self.size is None:
                raise ValueError("a box needs 'size' (x, y, z): its full extents in metres")
            if self.radius is not None or self.height is not None:
                raise ValueError("a box takes 'size' (x, y, z), not 'radius' or 'height'")
        else:
            if self.size is None:
                raise ValueError("a grill needs 'size' (x, y, z) of its body")
            if self.radius is not None:
                raise ValueError("a grill takes 'size', not 'radius'")
            reach = self.size[2] - GRILL_HANDLE_HALF_HEIGHT
            if self.handle_height is not None and not (
                GRILL_HANDLE_HALF_HEIGHT <= self.handle_height <= reach
            ):
                raise ValueError(
                    f"a grill's handle_height must lie between {GRILL_HANDLE_HALF_HEIGHT:g} and "
                    f"its height less {GRILL_HANDLE_HALF_HEIGHT:g} ({reach:g} m)"
                )
        if self.shape != "grill" and self.handle_height is not None:
            raise ValueError(f"a {self.shape} has no handles: 'handle_height' is for a grill")
        return self

    @model_serializer(mode="wrap")
    def _without_unset_handles(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """An object without ``handle_height`` (or a mesh's ``mesh`` and ``scale``) dumps as it
        did before the field existed, so
        every problem's :attr:`~stalm.world.problem.Problem.content_hash` (which results
        record) stays what it was."""
        data: dict[str, Any] = handler(self)
        for field in ("handle_height", "mesh", "scale"):
            if data.get(field, 0) is None:
                data.pop(field)
        return data

    @property
    def handle_z(self) -> float:
        """A grill's handles' (and grasp points') height above its bottom."""
        assert self.size is not None
        if self.handle_height is not None:
            return self.handle_height
        return self.size[2] * 0.75

    @property
    def half_extents(self) -> tuple[float, float, float]:
        """Half extents of the object's bounding box in its own frame (handles included)."""
        if self.shape == "grill":
            assert self.size is not None
            sx, sy, sz = self.size
            return (sx / 2, sy / 2 + GRILL_HANDLE_REACH, sz / 2)
        if self.shape == "box":
            assert self.size is not None
            return (self.size[0] / 2, self.size[1] / 2, self.size[2] / 2)
        if self.shape == "mesh":
            return self.outline.half_extents
        assert self.radius is not None and self.height is not None
        return (self.radius, self.radius, self.height / 2)


GRILL_HANDLE_REACH = 0.06
"""How far a grill's side handles stick out of its body (m)."""
GRILL_HANDLE_HALF_HEIGHT = 0.02
"""Half a grill handle's height and depth (m): a bar 4 cm square."""
