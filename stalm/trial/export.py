"""The executed plan of a result as timed trajectories a robot controller can run.

The output is JSON whose trajectories have the fields of ROS's ``trajectory_msgs/JointTrajectory``
(``joint_names``; ``points``, each with ``positions``, ``velocities``, ``accelerations`` in
``joint_names`` order and ``time_from_start`` in seconds), one per motion: each action's base
drive (a planar joint: ``base_x``, ``base_y`` in metres, ``base_yaw`` in radians, in the world
frame) and its arm motion (the lift in metres, then the arm's joints as the URDF names them).
``start_time`` says when a trajectory starts, in seconds from the plan's start, and the events
say when the hand grasps (close the gripper, attach the object), releases (open, detach) and
opens a door. The robot's URDF (its name in ``pybullet_data`` and the SHA-256 of the file), the
limits the plan was timed under and the problem's hash identify what the trajectories are for.

A result file is not trusted: its plan is replayed in a fresh scene first
(:func:`stalm.trial.replay.replay_result_json`), and a plan a step of which fails there is not
exported. Every exported point is checked against the limits (:func:`limit_violations`) before
the trajectories are returned.
"""

from __future__ import annotations

import math

import numpy as np

from stalm.domain.schedule import GRASP, RELEASE, PlanSchedule, schedule_plan
from stalm.errors import StalmError
from stalm.json_object import JsonObject, record_json
from stalm.motion.timing import LIMIT_SCALE, MotionSamples, TimedMotion
from stalm.trial.replay import replay_result_json
from stalm.world.problem import PROBLEM_HASH_FIELD, Problem
from stalm.world.robot import GRASP_FRAME, MOUNT_DESCRIPTION
from stalm.world.robot_description import FixedMount, Robot, is_builtin_panda
from stalm.world.robot_limits import RobotLimits, limits_of

EXPORT_FORMAT = "stalm-trajectories/1"
"""The ``format`` field of an export: the schema's name and version."""
DEFAULT_RATE = 50.0
"""Samples a second of an exported trajectory (besides every waypoint and the end)."""
RATE_RANGE = (1.0, 1000.0)
"""Sample rates ``stalm export --rate`` accepts (Hz)."""
BASE_JOINTS = ("base_x", "base_y", "base_yaw")
"""The base's planar joint, as the trajectories name its coordinates."""
LIMIT_TOLERANCE = 1e-6
"""Relative excess over a limit :func:`limit_violations` forgives (float rounding only: the
plan is timed at :data:`~stalm.motion.timing.LIMIT_SCALE` of the limits)."""
AT_REST = 1e-9
"""Speed (m/s or rad/s) below which a trajectory's first and last points are at rest."""


def check_rate(rate: float) -> float:
    low, high = RATE_RANGE
    if not (math.isfinite(rate) and low <= rate <= high):
        raise StalmError(f"--rate {rate}: the sample rate must be {low:g} to {high:g} Hz")
    return rate


def export_result(
    problem: Problem,
    data: JsonObject,
    rate: float = DEFAULT_RATE,
    source: str = "",
    limits: RobotLimits | None = None,
) -> tuple[JsonObject, tuple[str, ...]]:
    """The trajectories of the result ``data`` (planned for ``problem``) and the warnings of
    its replay; a StalmError if a step of its plan fails when replayed."""
    check_rate(rate)
    report = replay_result_json(problem, data)
    if report.failed_step is not None:
        raise StalmError(
            f"step {report.failed_step + 1} of the plan fails when it is replayed "
            f"({report.reason}): a plan that does not replay is not exported"
        )
    warnings = list(report.warnings)
    if not report.reached_goal:
        warnings.append(f"the plan does not reach the goal ({report.reason})")
    schedule = schedule_plan(report.actions, limits or limits_of(problem.robot))
    exported = trajectories_json(problem, schedule, rate)
    exported["source"] = source
    exported["reached_goal"] = report.reached_goal
    violations = limit_violations(exported, schedule.limits)
    if violations:  # the timing keeps a margin; this guards it
        raise RuntimeError(f"the timed plan exceeds a limit: {violations[0]}")
    return exported, tuple(warnings)


def _trajectory(
    motion: TimedMotion, start: float, rate: float, names: tuple[str, ...]
) -> JsonObject:
    samples: MotionSamples = motion.sample(rate)
    points = [
        {
            "positions": samples.positions[row].tolist(),
            "velocities": samples.velocities[row].tolist(),
            "accelerations": samples.accelerations[row].tolist(),
            "time_from_start": float(samples.times[row]),
        }
        for row in range(len(samples.times))
    ]
    return {
        "start_time": start,
        "duration": motion.duration,
        "waypoint_times": list(motion.waypoint_times),
        "joint_names": list(names),
        "points": points,
    }


def trajectories_json(problem: Problem, schedule: PlanSchedule, rate: float) -> JsonObject:
    """The export of ``schedule`` (see the module docstring), sampled at ``rate``."""
    limits = schedule.limits
    robot_entry = _robot_entry(problem.robot, limits)
    grasp_frame = robot_entry["grasp_frame"]
    trajectories = []
    for index, timing in enumerate(schedule.actions):
        step = str(timing.action)
        for motion, kind, start, names in (
            (timing.base, "base", timing.start, BASE_JOINTS),
            (timing.arm, "arm", timing.arm_start, limits.arm.names),
        ):
            trajectory = _trajectory(motion, start, rate, names)
            trajectories.append({"action": index, "step": step, "motion": kind, **trajectory})
    events = []
    for event in schedule.events:
        action = schedule.actions[event.action].action
        entry: JsonObject = {"time": event.time, "action": event.action, "event": event.kind}
        if event.kind == GRASP:
            grasp = action.params.grasp  # type: ignore[union-attr]
            entry.update(
                object=event.name,
                frame=grasp_frame,
                grasp={"position": list(grasp.position), "orientation": list(grasp.orientation)},
            )
        elif event.kind == RELEASE:
            pose = action.params.placement  # type: ignore[union-attr]
            entry.update(object=event.name, placement=[pose.x, pose.y, pose.z, pose.yaw])
        else:
            door = problem.spec.door(event.name)
            entry.update(door=event.name, closed_yaw=door.closed_yaw, open_yaw=door.open_yaw)
        events.append(entry)
    return {
        "format": EXPORT_FORMAT,
        "problem": problem.name,
        PROBLEM_HASH_FIELD: problem.content_hash,
        "robot": robot_entry,
        "limits": {
            "scale": LIMIT_SCALE,
            "base": record_json(limits.base),
            "arm": {
                "joint_names": list(limits.arm.names),
                "velocity": list(limits.arm.velocity),
                "acceleration": list(limits.arm.acceleration),
            },
        },
        "rate": rate,
        "duration": schedule.duration,
        "trajectories": trajectories,
        "events": events,
    }


def _robot_entry(robot: Robot, limits: RobotLimits) -> JsonObject:
    """What the export says of the robot: its URDF, its mount and the frame grasps are in
    (another robot's: its tool link moved by ``tool_offset``, both stated)."""
    entry: JsonObject = {
        "urdf": limits.urdf,
        "urdf_sha256": limits.urdf_sha256,
        "mount": MOUNT_DESCRIPTION,
        "grasp_frame": GRASP_FRAME,
    }
    if is_builtin_panda(robot):
        return entry
    mount = robot.spec.mount
    if isinstance(mount, FixedMount):
        x, y, z = mount.xyz
        entry["mount"] = (
            f"fixed at ({x:g}, {y:g}, {z:g}) m, yaw {mount.yaw:g} rad: the base never moves "
            "and the 'lift' joint stays at the mount's height"
        )
    offset = robot.spec.tool_offset
    entry.update(
        grasp_frame=robot.spec.tool_link,
        tool_offset={"xyz": list(offset.xyz), "rpy": list(offset.rpy)},
    )
    return entry


def _over(values: np.ndarray, limit: float | np.ndarray, tolerance: float) -> bool:
    return bool(np.any(np.abs(values) > np.asarray(limit) * (1 + tolerance)))


def limit_violations(
    exported: JsonObject, limits: RobotLimits, tolerance: float = LIMIT_TOLERANCE
) -> list[str]:
    """Every way the trajectories of ``exported`` break ``limits`` (empty if none): a velocity
    or acceleration over its limit at a point (the base's speed and acceleration along its
    path, as vectors), a trajectory that does not start and end at rest, or times that do not
    increase."""
    found = []
    for number, trajectory in enumerate(exported["trajectories"]):
        where = f"trajectory {number} ({trajectory['step']}, {trajectory['motion']})"
        points = trajectory["points"]
        times = np.array([point["time_from_start"] for point in points])
        v = np.array([point["velocities"] for point in points])
        a = np.array([point["accelerations"] for point in points])
        if np.any(np.diff(times) <= 0):
            found.append(f"{where}: times do not increase")
        if np.any(np.abs(v[[0, -1]]) > AT_REST):
            found.append(f"{where}: does not start and end at rest")
        if trajectory["motion"] == "base":
            base = limits.base
            checks = [
                ("speed", np.linalg.norm(v[:, :2], axis=1), base.speed),
                ("acceleration", np.linalg.norm(a[:, :2], axis=1), base.acceleration),
                ("turn rate", v[:, 2], base.turn_rate),
                ("turn acceleration", a[:, 2], base.turn_acceleration),
            ]
            for what, values, limit in checks:
                if _over(values, limit, tolerance):
                    found.append(f"{where}: {what} {np.abs(values).max():.4g} over {limit:g}")
            continue
        if tuple(trajectory["joint_names"]) != limits.arm.names:
            found.append(f"{where}: joints {trajectory['joint_names']} are not the limits'")
            continue
        for what, values, bounds in (
            ("velocity", v, np.asarray(limits.arm.velocity)),
            ("acceleration", a, np.asarray(limits.arm.acceleration)),
        ):
            if _over(values, bounds, tolerance):
                joint = int(np.argmax((np.abs(values) / bounds).max(axis=0)))
                found.append(
                    f"{where}: {limits.arm.names[joint]} {what} "
                    f"{np.abs(values[:, joint]).max():.4g} over {bounds[joint]:g}"
                )
    return found
