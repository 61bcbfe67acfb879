"""Scene images with PyBullet's TinyRenderer (CPU, headless): a top-down and a perspective view.

Used by ``stalm render`` and by plan animations; a picture of a State is the quickest way to
see what a problem file or a plan does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pybullet as p
from PIL import Image

from stalm.errors import StalmError
from stalm.files import replacing
from stalm.viz.sizes import MAX_SIZE as MAX_SIZE
from stalm.viz.sizes import MIN_SIZE as MIN_SIZE
from stalm.viz.sizes import check_size
from stalm.world.scene import Sim
from stalm.world.state import State


def _camera_image(
    sim: Sim, view: list[float], projection: list[float], width: int, height: int
) -> Image.Image:
    _, _, rgba, _, _ = p.getCameraImage(
        width,
        height,
        viewMatrix=view,
        projectionMatrix=projection,
        renderer=p.ER_TINY_RENDERER,
        shadow=0,
        physicsClientId=sim.client,
    )
    pixels = np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))
    return Image.fromarray(pixels[:, :, :3], "RGB")


def top_down(sim: Sim, width: int = 640, height: int = 640) -> Image.Image:
    """The whole floor seen from straight above (x to the right, y up)."""
    (x0, y0), (x1, y1) = sim.problem.floor
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    span = max(x1 - x0, y1 - y0) + 0.6
    distance = 40.0
    fov = float(np.degrees(2 * np.arctan(span / 2 / distance)))
    view = p.computeViewMatrix(
        [cx, cy, distance], [cx, cy, 0.0], [0.0, 1.0, 0.0], physicsClientId=sim.client
    )
    projection = p.computeProjectionMatrixFOV(
        fov, width / height, distance - 5, distance + 1, physicsClientId=sim.client
    )
    return _camera_image(sim, view, projection, width, height)


def perspective(sim: Sim, width: int = 640, height: int = 480) -> Image.Image:
    """The scene from above the hall's south-east corner, looking at the kitchen."""
    view = p.computeViewMatrix(
        [5.5, -7.5, 7.5], [-1.0, 0.5, 0.5], [0.0, 0.0, 1.0], physicsClientId=sim.client
    )
    projection = p.computeProjectionMatrixFOV(
        55, width / height, 0.1, 40, physicsClientId=sim.client
    )
    return _camera_image(sim, view, projection, width, height)


def render_state(sim: Sim, state: State, size: int = 640) -> Image.Image:
    """Top-down and perspective views of ``state`` side by side."""
    check_size(size)
    sim.set_state(state)
    left = top_down(sim, size, size)
    right = perspective(sim, size, size)
    canvas = Image.new("RGB", (2 * size, size), (255, 255, 255))
    canvas.paste(left, (0, 0))
    canvas.paste(right, (size, 0))
    return canvas


def save_render(sim: Sim, state: State, path: Path, size: int = 640) -> Path:
    image = render_state(sim, state, size)
    try:
        with replacing(path) as temp:  # all or nothing, as every file stalm writes over
            image.save(temp)
    except OSError as error:
        raise StalmError(f"{path}: cannot write the picture ({error.strerror or error})") from None
    return path
