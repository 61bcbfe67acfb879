"""Animations of a plan executing: the base driving, the arm moving, objects carried, the door
swinging. Frames are rendered with TinyRenderer (headless) and written as a GIF.

Rendering is what an animation costs (two TinyRenderer views, ~45 ms a frame whatever their
size: the robot's meshes dominate), so :func:`write_animation` renders one motion frame in
:data:`FRAME_STRIDE` and every action's last one (the state it leads to is always shown),
each shown for longer; :func:`plan_motion`, which ``stalm view``'s page follows, is unchanged.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from PIL import Image

from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.errors import StalmError
from stalm.files import replacing
from stalm.motion.arm_motion import interpolate, interpolate_waypoints
from stalm.motion.base_motion import BasePath, densify
from stalm.viz.render import perspective, top_down
from stalm.viz.sizes import GIF_SIZE, check_size
from stalm.world.scene import Sim
from stalm.world.state import State

BASE_STEP = 0.6
"""Metres the base moves between two frames."""
ARM_FRAMES = 3
"""Frames per arm motion segment between two waypoints."""
FRAME_STRIDE = 4
""":func:`write_animation` renders one motion frame in this many (and each action's last)."""
FRAME_MS = 200
"""How long :func:`write_animation` shows each frame."""


def _frame(sim: Sim, size: int) -> Image.Image:
    left = top_down(sim, size, size)
    right = perspective(sim, size, size)
    canvas = Image.new("RGB", (2 * size, size), (255, 255, 255))
    canvas.paste(left, (0, 0))
    canvas.paste(right, (size, 0))
    return canvas


def plan_frames(
    sim: Sim,
    start: State,
    plan: Sequence[tuple[Action, State]],
    size: int = GIF_SIZE,
    stride: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> list[Image.Image]:
    """Frames of ``plan``: pairs of an action and the state it leads to, from ``start``;
    with ``stride`` above 1 only the frames :func:`kept_frames` keeps. ``progress`` hears
    how many of them are rendered."""
    shown = kept_frames(list(plan_motion(sim, start, plan)), stride)
    frames: list[Image.Image] = []
    for index, _ in enumerate(plan_motion(sim, start, plan)):
        if index in shown:
            frames.append(_frame(sim, size))
            if progress is not None:
                progress(len(frames), len(shown))
    return frames


def kept_frames(actions: Sequence[int], stride: int) -> frozenset[int]:
    """Which frames of a motion to render, given the action each frame shows
    (:func:`plan_motion`'s yields): the first, one in ``stride`` of the rest, and the last of
    each action (the state it leads to)."""
    kept = {index for index in range(len(actions)) if index % stride == 0}
    kept |= {
        index
        for index in range(len(actions))
        if index + 1 == len(actions) or actions[index + 1] != actions[index]
    }
    return frozenset(kept)


def write_animation(
    sim: Sim,
    start: State,
    plan: Sequence[tuple[Action, State]],
    path: Path,
    size: int = GIF_SIZE,
    progress: Callable[[int, int], None] | None = None,
) -> int:
    """Render ``plan``'s animation (one frame in :data:`FRAME_STRIDE`, each action's last;
    two views of ``size`` pixels) and write it to ``path`` (:func:`save_gif`); the frames
    written. ``progress`` hears how many frames are rendered, of how many."""
    check_size(size, "--gif-size")
    frames = plan_frames(sim, start, plan, size, FRAME_STRIDE, progress)
    save_gif(frames, path, FRAME_MS)
    return len(frames)


@dataclass(frozen=True)
class FramePlace:
    """Where a frame of :func:`plan_motion` is in the plan: the action (-1 for the start) and
    its ``motion``: ``base`` or ``arm`` partway through a straight move (from waypoint
    ``move`` to the next, ``fraction`` of the way), or ``end`` (the door swinging and the
    state the action leads to, after its motions). :mod:`stalm.domain.schedule` gives the
    robot time of each."""

    action: int
    motion: str
    move: int = 0
    fraction: float = 1.0


def plan_motion(sim: Sim, start: State, plan: Sequence[tuple[Action, State]]) -> Iterator[int]:
    """Set ``sim`` to each frame of ``plan`` in turn (the base driving, the arm moving, the
    door swinging) and yield, while it shows that frame, the index of the action being
    executed (-1 for the start). The GIF and ``stalm view``'s page both follow this motion,
    so they show the same thing."""
    for place in plan_motion_places(sim, start, plan):
        yield place.action


def _base_places(path: BasePath, resolution: float) -> list[tuple[int, float]]:
    """(corner pair, fraction of it) of each waypoint of ``densify(path, resolution)`` after
    the first, as densify steps along the pairs; a path of no length is all at its end."""
    count = len(densify(path, resolution)) - 1
    if path.length == 0.0:
        return [(len(path.corners), 1.0)] * count
    places = []
    for pair, (a, b) in enumerate(itertools.pairwise(path.corners)):
        steps = max(1, math.ceil(math.dist(a[:2], b[:2]) / resolution))
        places += [(pair, i / steps) for i in range(1, steps + 1)]
    return places


def _arm_places(waypoints: Sequence[tuple[float, ...]]) -> list[tuple[int, float]]:
    """(waypoint pair, fraction of it) of each configuration of
    ``interpolate_waypoints(waypoints)``."""
    places = [(0, 0.0)]
    for pair, (a, b) in enumerate(itertools.pairwise(waypoints)):
        steps = len(interpolate(a, b)) - 1
        places += [(pair, i / steps) for i in range(1, steps + 1)]
    return places


def plan_motion_places(
    sim: Sim, start: State, plan: Sequence[tuple[Action, State]]
) -> Iterator[FramePlace]:
    """:func:`plan_motion`, yielding where in the plan each frame is."""
    state = start
    sim.set_state(state)
    yield FramePlace(-1, "start")
    for number, (action, next_state) in enumerate(plan):
        params = action.params
        sim.set_state(state)
        path = densify(params.base_path, BASE_STEP)
        for pose, (pair, fraction) in zip(
            path[1:], _base_places(params.base_path, BASE_STEP), strict=True
        ):
            sim.set_base_only(pose)
            yield FramePlace(number, "base", pair, fraction)
        stand = params.base_path.corners[-1]
        sim.set_base_only(stand)
        if isinstance(params, PickParams):
            split = params.arm_waypoints.index(params.grasp_conf)
        elif isinstance(params, PlaceParams):
            split = params.arm_waypoints.index(params.place_conf)
        else:
            split = params.arm_waypoints.index(params.handle_conf)
        dense = interpolate_waypoints(list(params.arm_waypoints))
        arm_places = _arm_places(params.arm_waypoints)
        grasp_index = _index_of(dense, params.arm_waypoints[split])
        step = max(1, len(dense) // (ARM_FRAMES * max(1, len(params.arm_waypoints) - 1)))
        for index in range(0, len(dense), step):
            if index >= grasp_index and isinstance(params, PickParams):
                sim.attach(params.grasp)
            if index >= grasp_index and isinstance(params, PlaceParams):
                sim.attach(None)
                sim.place_object(action.discrete.as_tuple()[1], params.placement)
            conf = dense[index]
            sim.set_arm(stand, conf[0], conf[1:])
            yield FramePlace(number, "arm", *arm_places[index])
        if isinstance(params, OpenParams):
            door = sim.problem.door(action.discrete.as_tuple()[1])
            for t in (0.25, 0.5, 0.75, 1.0):
                yaw = door.closed_yaw + t * math.remainder(
                    door.open_yaw - door.closed_yaw, math.tau
                )
                sim.set_door_angle(door.name, yaw)
                yield FramePlace(number, "end")
        state = next_state
        sim.set_state(state)
        yield FramePlace(number, "end")


def _index_of(dense: list[tuple[float, ...]], conf: tuple[float, ...]) -> int:
    best, best_distance = 0, math.inf
    for index, candidate in enumerate(dense):
        distance = sum(abs(a - b) for a, b in zip(candidate, conf, strict=True))
        if distance < best_distance:
            best, best_distance = index, distance
    return best


def save_gif(frames: Sequence[Image.Image], path: Path, frame_ms: int = 120) -> Path:
    """Write the animation to ``path`` all or nothing (:func:`stalm.files.replacing`: a full
    disk leaves the file that was there); a StalmError naming the path if it cannot."""
    try:
        with replacing(path) as temp:
            frames[0].save(
                temp,
                save_all=True,
                append_images=list(frames[1:]),
                duration=frame_ms,
                loop=0,
                optimize=True,
            )
    except OSError as error:
        raise StalmError(
            f"{path}: cannot write the animation ({error.strerror or error})"
        ) from None
    return path
