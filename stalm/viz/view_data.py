"""What ``stalm view``'s page shows, taken from a result file: the scene as triangle meshes, the
executed plan as frames of body poses, the plan's continuous parameters, and the search's
per-step record.

The scene is not pictured but rebuilt: the problem's bodies are PyBullet boxes and cylinders
made from its spec (:mod:`stalm.world.scene`); their shapes are read back from the simulator
and turned into triangle meshes in each body's own frame, so the page shows exactly the
geometry the planner checked collisions against, and the browser moves the meshes itself.
The frames follow :func:`stalm.viz.animate.plan_motion`, the motion the GIF shows: per frame
the pose of every body that moves (doors, objects, the robot's base and lift) and the Panda's
joint positions, drawn as a stick figure (its links are meshes, not primitives), and its time
in seconds of robot time, from the timing ``stalm export`` writes
(:mod:`stalm.domain.schedule`).

A result file is not trusted: its plan is replayed in a fresh scene from the problem's own
initial state (:func:`stalm.trial.replay.replay_result_json`), which gives the states the
motion goes through and confirms the plan; a step that fails there ends the animation with a
note. Anything an older file lacks (the per-step record) becomes a note, never an error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p

from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.domain.schedule import PlanSchedule, schedule_plan
from stalm.trial.replay import replay_result_json
from stalm.trial.result import phase_times_json
from stalm.trial.step_log import DECISIONS
from stalm.viz.animate import plan_motion_places
from stalm.world.mesh_files import read_obj
from stalm.world.problem import Problem
from stalm.world.robot_description import is_builtin_panda
from stalm.world.robot_limits import limits_of
from stalm.world.scene import Sim
from stalm.world.state import State

CYLINDER_SIDES = 20
"""Facets of a cylinder's mantle: round enough for a can, few enough to keep the page small."""
ARM_LINKS = tuple(range(9))
"""Panda links 0..8 (link1 to the hand) drawn as the arm's stick figure."""
FINGER_LINKS = (9, 11, 10)
"""Left fingertip, grasp point, right fingertip: the gripper's bar."""
POSITION_DIGITS = 4
"""Decimals kept of a coordinate in the page (0.1 mm)."""
TIME_DIGITS = 3
"""Decimals kept of a frame's robot time in the page (1 ms)."""


# ---------------------------------------------------------------------------- meshes


def _rotate(quat: Sequence[float], points: np.ndarray) -> np.ndarray:
    """``points`` (n x 3) rotated by the quaternion (x, y, z, w)."""
    matrix = np.asarray(p.getMatrixFromQuaternion(list(quat)), dtype=float).reshape(3, 3)
    return points @ matrix.T


def _box(size: Sequence[float]) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    sx, sy, sz = (s / 2 for s in size[:3])
    corners = np.array(
        [[x, y, z] for z in (-sz, sz) for y in (-sy, sy) for x in (-sx, sx)], dtype=float
    )
    # corners: index = 4*top + 2*(y>0) + (x>0)
    faces = [
        (0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6),  # bottom, top
        (0, 1, 4), (1, 5, 4), (2, 6, 3), (3, 6, 7),  # -y, +y
        (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5),  # -x, +x
    ]  # fmt: skip
    return corners, faces


def _cylinder(radius: float, length: float) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    n = CYLINDER_SIDES
    angles = np.arange(n) * (2 * math.pi / n)
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    bottom = np.column_stack([ring, np.full(n, -length / 2)])
    top = np.column_stack([ring, np.full(n, length / 2)])
    centres = np.array([[0.0, 0.0, -length / 2], [0.0, 0.0, length / 2]])
    points = np.vstack([bottom, top, centres])
    faces: list[tuple[int, int, int]] = []
    for k in range(n):
        a, b = k, (k + 1) % n
        faces += [(a, b, n + a), (b, n + b, n + a), (2 * n, b, a), (2 * n + 1, n + a, n + b)]
    return points, faces


def _obj_triangles(
    file_name: str, scale: Sequence[float]
) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    """The triangles of a mesh object's OBJ (every piece), scaled: the mesh as it is drawn."""
    pieces = read_obj(Path(file_name))
    points, faces, count = [], [], 0
    for vertices, triangles in zip(pieces.vertices, pieces.triangles, strict=True):
        points.append(vertices * np.asarray(scale[:3]))
        faces += [(int(a) + count, int(b) + count, int(c) + count) for a, b, c in triangles]
        count += len(vertices)
    return np.vstack(points), faces


def _color(rgba: Sequence[float]) -> str:
    r, g, b = (round(255 * min(1.0, max(0.0, float(c)))) for c in rgba[:3])
    return f"rgb({r},{g},{b})"


class _Mesh:
    """Triangles gathered from shapes: vertices, faces and one colour per face."""

    def __init__(self) -> None:
        self.points: list[np.ndarray] = []
        self.faces: list[tuple[int, int, int]] = []
        self.colors: list[str] = []
        self.count = 0

    def add_body(self, sim: Sim, body: int, world: bool) -> int:
        """Add ``body``'s box, cylinder and mesh shapes, in its own frame or (``world``) where it
        stands now; return how many vertices were added."""
        added = 0
        origin, orientation = p.getBasePositionAndOrientation(body, physicsClientId=sim.client)
        for shape in p.getVisualShapeData(body, physicsClientId=sim.client):
            geometry, dimensions, position, quat, rgba = (
                shape[2], shape[3], shape[5], shape[6], shape[7],
            )  # fmt: skip
            if geometry == p.GEOM_BOX:
                points, faces = _box(dimensions)
            elif geometry == p.GEOM_CYLINDER:
                points, faces = _cylinder(dimensions[1], dimensions[0])
            elif geometry == p.GEOM_MESH:  # a mesh object (the Panda is a stick figure)
                points, faces = _obj_triangles(shape[4].decode(), dimensions)
            else:
                continue
            points = _rotate(quat, points) + np.asarray(position)
            if world:
                points = _rotate(orientation, points) + np.asarray(origin)
            self.points.append(points)
            self.faces += [(a + self.count, b + self.count, c + self.count) for a, b, c in faces]
            self.colors += [_color(rgba)] * len(faces)
            self.count += len(points)
            added += len(points)
        return added

    def to_json(self) -> dict[str, Any]:
        points = np.vstack(self.points) if self.points else np.zeros((0, 3))
        rounded = np.round(points, POSITION_DIGITS)
        return {
            "x": rounded[:, 0].tolist(),
            "y": rounded[:, 1].tolist(),
            "z": rounded[:, 2].tolist(),
            "i": [f[0] for f in self.faces],
            "j": [f[1] for f in self.faces],
            "k": [f[2] for f in self.faces],
            "facecolor": self.colors,
        }


def _moving_bodies(sim: Sim) -> list[tuple[str, str, int]]:
    """(name, role, body id) of every body that moves: doors, objects, the robot's base."""
    bodies = sim.bodies
    moving = [(name, "door", body) for name, body in bodies.doors.items()]
    moving += [(name, "object", body) for name, body in bodies.objects.items()]
    moving.append(("robot", "robot", bodies.base))
    return moving


def scene_meshes(sim: Sim) -> dict[str, Any]:
    """The scene's meshes: the floor and regions in world coordinates, the walls apart (the
    page draws them see-through), and every moving body in its own frame, one after another
    in one mesh whose vertex ranges ``bodies`` gives."""
    ground, walls, moving = _Mesh(), _Mesh(), _Mesh()
    ground.add_body(sim, sim.bodies.floor, world=True)
    for body in sim.bodies.regions.values():
        ground.add_body(sim, body, world=True)
    for body in sim.bodies.walls.values():
        walls.add_body(sim, body, world=True)
    ranges = []
    for name, role, body in _moving_bodies(sim):
        start = moving.count
        count = moving.add_body(sim, body, world=False)
        ranges.append({"name": name, "role": role, "start": start, "count": count})
    return {
        "ground": ground.to_json(),
        "walls": walls.to_json(),
        "moving": moving.to_json(),
        "bodies": ranges,
    }


# ---------------------------------------------------------------------------- frames


def _rounded(values: Sequence[float]) -> list[float]:
    return [round(float(v), POSITION_DIGITS) + 0.0 for v in values]


def _frame(sim: Sim, moving: list[tuple[str, str, int]]) -> tuple[list[float], list[Any]]:
    """Poses (x, y, z, qx, qy, qz, qw per moving body) and the arm's stick figure (a polyline
    of joint positions, a gap, the gripper bar) of what ``sim`` shows now."""
    c = sim.client
    poses: list[float] = []
    for _, _, body in moving:
        position, orientation = p.getBasePositionAndOrientation(body, physicsClientId=c)
        poses += _rounded(position) + _rounded(orientation)
    arm = sim.bodies.arm
    mount, _ = p.getBasePositionAndOrientation(arm, physicsClientId=c)

    def at(link: int) -> tuple[float, ...]:
        return tuple(p.getLinkState(arm, link, computeForwardKinematics=True, physicsClientId=c)[4])

    joints = sim.bodies.joints
    if is_builtin_panda(sim.robot):
        figure: list[Any] = [_rounded(mount)] + [_rounded(at(link)) for link in ARM_LINKS]
        figure.append(None)
        figure += [_rounded(at(link)) for link in FINGER_LINKS]
        return poses, figure
    # any other arm: each joint's link, the grasp point, then the bar across the fingers
    grasp = sim.gripper_pose()[0]
    figure = [_rounded(mount), *(_rounded(at(link)) for link in joints.arm), _rounded(grasp), None]
    if len(joints.finger_links) == 2:
        left, right = joints.finger_links
        figure += [_rounded(at(left)), _rounded(grasp), _rounded(at(right))]
    return poses, figure


def motion_frames(
    sim: Sim,
    start: State,
    plan: Sequence[tuple[Action, State]],
    schedule: PlanSchedule | None = None,
) -> dict[str, Any]:
    """Every frame of the plan's motion: the action it belongs to (-1: the start), its robot
    time (seconds from the plan's start, as ``stalm export`` times the plan: the same
    parameterisation under the robot's limits; ``schedule`` if given, else the plan timed
    under today's robot's), the poses of the moving bodies (in :func:`scene_meshes`' order)
    and the arm's figure."""
    moving = _moving_bodies(sim)
    if schedule is None:
        schedule = schedule_plan([action for action, _ in plan], limits_of(sim.robot))
    places: list[tuple[int, str, int, float]] = []
    poses: list[list[float]] = []
    arms: list[list[Any]] = []
    for place in plan_motion_places(sim, start, plan):
        frame_poses, arm = _frame(sim, moving)
        places.append((place.action, place.motion, place.move, place.fraction))
        poses.append(frame_poses)
        arms.append(arm)
    times = [round(time, TIME_DIGITS) for time in schedule.times_of(places)]
    actions = [action for action, _, _, _ in places]
    return {"action": actions, "time": times, "poses": poses, "arm": arms}


# ---------------------------------------------------------------------------- the plan


def describe_params(action: Action) -> str:
    """One line of an action's continuous parameters, as the page's plan table shows them."""
    params = action.params
    x, y, yaw = params.base_path.corners[-1]
    text = (
        f"base path {params.base_path.length:.2f} m ({len(params.base_path.corners)} corners) "
        f"to ({x:.2f}, {y:.2f}, yaw {yaw:.2f})"
    )
    if isinstance(params, PickParams):
        text += (
            f"; gripper pitch {params.pitch:.2f}, yaw {params.yaw:.2f}; lift "
            f"{params.grasp_conf[0]:.2f} m"
        )
    elif isinstance(params, PlaceParams):
        pose = params.placement
        text += f"; placed at ({pose.x:.3f}, {pose.y:.3f}, {pose.z:.3f}), yaw {pose.yaw:.2f}"
    elif isinstance(params, OpenParams):
        text += f"; handle reached at lift {params.handle_conf[0]:.2f} m"
    return text + f"; {len(params.arm_waypoints)} arm waypoints"


def _plan_rows(
    data: dict[str, Any], parsed: Sequence[Action], schedule: PlanSchedule
) -> list[dict[str, Any]]:
    raw = data.get("plan") if isinstance(data.get("plan"), list) else []
    rows = []
    for index, item in enumerate(raw or []):
        action = item.get("action") if isinstance(item, dict) else None
        row: dict[str, Any] = {
            "action": action if isinstance(action, list) else [str(action)],
            "params": item,
        }
        if index < len(parsed):
            row["summary"] = describe_params(parsed[index])
        if index < len(schedule.actions):
            timing = schedule.actions[index]
            row["robot_time"] = [round(timing.start, TIME_DIGITS), round(timing.end, TIME_DIGITS)]
        rows.append(row)
    return rows


# ---------------------------------------------------------------------------- all of it


def view_data(problem: Problem, data: dict[str, Any], source: str = "") -> dict[str, Any]:
    """Everything the page needs, as JSON-able data; ``notes`` says what the file lacks."""
    notes: list[str] = []
    replay: dict[str, Any]
    parsed: tuple[Action, ...] = ()
    states: tuple[State, ...] = (problem.initial_state,)
    if data.get("termination") == "error":
        replay = {"reached_goal": False, "steps": 0, "reason": "the run ended in an error"}
        notes.append(f"the run ended in an error: {str(data.get('error'))[:300]}")
    else:
        report = replay_result_json(problem, data)
        notes += report.warnings
        parsed, states = report.actions, report.states
        replay = {
            "reached_goal": report.reached_goal,
            "steps": report.steps_executed,
            "failed_step": report.failed_step,
            "reason": report.reason,
        }
        if report.failed_step is not None:
            notes.append(
                f"replaying the plan in a fresh scene fails at action {report.failed_step + 1} "
                f"({report.reason}); the animation stops before it"
            )
    pairs = list(zip(parsed, states[1:], strict=False))
    schedule = schedule_plan([action for action, _ in pairs], limits_of(problem.robot))
    with Sim(problem.spec) as sim:
        sim.set_state(problem.initial_state)
        meshes = scene_meshes(sim)
        frames = motion_frames(sim, states[0], pairs, schedule)
    details = data.get("details") if isinstance(data.get("details"), dict) else {}
    step_log = details.get("step_log") if isinstance(details, dict) else None
    if not isinstance(step_log, list):
        step_log = None
        notes.append(
            "this result file holds no per-step record (details.step_log: written by STaLM "
            "and the UCT planners of a newer stalm): the task plans proposed, their failures "
            "and the search trees cannot be shown"
        )
    (x0, y0), (x1, y1) = problem.spec.floor
    return {
        "source": source,
        "problem": problem.name,
        "description": problem.spec.description,
        "goal": [str(atom) for atom in problem.goal],
        "floor": [[x0, y0], [x1, y1]],
        "result": {
            **{key: data.get(key) for key in ("planner", "seed", "success", "termination")},
            "times": phase_times_json(data.get("times")),
            "counters": data.get("counters"),
        },
        "llm_plan_failures": data.get("llm_plan_failures") or {},
        "proposer": details.get("proposer") if isinstance(details, dict) else None,
        "replay": replay,
        "plan": _plan_rows(data, parsed, schedule),
        "scene": meshes,
        "frames": frames,
        "step_log": step_log,
        "decisions": DECISIONS,
        "notes": notes,
    }
