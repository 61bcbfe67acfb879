"""Re-check a sampled action in a given state: every motion swept again against the scene.

Within the search, κ is checked when it is drawn and T then applies it without checking again.
A saved plan replayed in a fresh scene (``stalm replay``) goes through :func:`check_action`
first, so a plan file that does not fit the world is reported, never silently executed.

A plan file can also be *edited*. The motions of a forged action may well be collision-free
while the action does not do what it says: a base path that starts somewhere else than the
robot (a teleport), a grasp nowhere near the object or holding it turned from how it stands, a
placement the hand never reaches (or turned from how the hand holds the object) or on another
region, an object placed into a wall or another object, an arm motion cut so that the
arm jumps from the configuration it holds to the grasp (its first motion never swept).
:func:`check_consistency` (before the action) and :func:`check_outcome` (on the state it
produces) catch those; a sampled action passes them by construction, so they never reject a
planner's own plan. The numbers themselves are bounded before any of this
(:mod:`stalm.domain.plan_bounds`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.outcome import Infeasibility
from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.domain.plan_bounds import SWEEP_RESOLUTION
from stalm.geometry.transforms import (
    Pose3,
    Quat,
    angle_between_rotations,
    compose,
    matrix_from_quat,
    wrap_angle,
    yaw_quat,
)
from stalm.motion.arm_motion import first_collision, interpolate_waypoints
from stalm.motion.base_motion import densify
from stalm.world.relations import at_position, supporting_region
from stalm.world.scene import Sim
from stalm.world.spec import ProblemSpec
from stalm.world.state import State

POSE_TOLERANCE = 1e-3
"""How close (m, rad) a path's start must be to the robot, and its end to the standing pose;
and an arm motion's ends to the configurations the robot holds before and after the action."""
REACH_TOLERANCE = 0.02
"""How close (m) the hand at a key configuration must bring the object or reach the handle:
four times the IK's tolerance, far below what a forged value that matters would move."""
TURN_TOLERANCE = 0.1
"""How far (rad) the object in the hand at a key configuration may be turned from how it stands
(a pick) or from its saved placement (a place): over three times the IK's angle tolerance
(placed objects of committed plans are within 0.02 rad)."""


def _split(
    waypoints: tuple[tuple[float, ...], ...], at: tuple[float, ...]
) -> tuple[list[tuple[float, ...]], list[tuple[float, ...]]]:
    index = waypoints.index(at)
    return list(waypoints[: index + 1]), list(waypoints[index:])


def check_action(
    sim: Sim, state: State, action: Action, resolution: float = SWEEP_RESOLUTION
) -> Infeasibility | None:
    """None if ``action``'s motions are collision-free in ``state``; else why not."""
    params = action.params
    sim.set_state(state)
    names = sim.bodies.name_of
    for pose in densify(params.base_path, resolution):
        sim.set_base_only(pose)
        hits = sim.robot_contacts()
        if hits:
            return Infeasibility(
                "base_path_blocked",
                "the saved base path collides",
                tuple(sorted(names(b) for b in hits)),
            )
    stand = params.base_path.corners[-1]
    sim.set_base_only(stand)
    if isinstance(params, PickParams):
        target = sim.bodies.objects[action.discrete.as_tuple()[1]]
        approach, lift = _split(params.arm_waypoints, params.grasp_conf)
        hits = first_collision(sim, stand, interpolate_waypoints(approach), {target})
        if not hits:
            sim.attach(params.grasp)
            hits = first_collision(sim, stand, interpolate_waypoints(lift))
            sim.attach(None)
    elif isinstance(params, PlaceParams):
        obj = action.discrete.as_tuple()[1]
        body = sim.bodies.objects[obj]
        lower, retreat = _split(params.arm_waypoints, params.place_conf)
        hits = first_collision(sim, stand, interpolate_waypoints(lower))
        if not hits:
            sim.attach(None)
            sim.place_object(obj, params.placement)
            hits = sim.contacts_of([body], (sim.bodies.base, sim.bodies.arm))
            if not hits:
                hits = first_collision(sim, stand, interpolate_waypoints(retreat), {body})
    else:
        assert isinstance(params, OpenParams)
        door = sim.bodies.doors[action.discrete.as_tuple()[1]]
        hits = first_collision(
            sim, stand, interpolate_waypoints(list(params.arm_waypoints)), {door}
        )
    if hits:
        return Infeasibility(
            "arm_collision",
            f"the saved motion of {action.discrete} collides",
            tuple(sorted(names(b) for b in hits)),
        )
    return None


def _same_pose(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return (
        math.dist(a[:2], b[:2]) <= POSE_TOLERANCE and abs(wrap_angle(a[2] - b[2])) <= POSE_TOLERANCE
    )


def _same_conf(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return all(abs(x - y) <= POSE_TOLERANCE for x, y in zip(a, b, strict=True))


def _hand_at(sim: Sim, stand: tuple[float, float, float], conf: tuple[float, ...]) -> Pose3:
    """The gripper's pose with the base at ``stand`` and the lift and arm at ``conf``."""
    sim.set_base_only(stand)
    sim.set_arm(stand, conf[0], conf[1:])
    return sim.gripper_pose()


def _turn(held: Quat, yaw: float) -> float:
    """The angle (rad) between an orientation of a held object and the object upright at
    ``yaw``."""
    return angle_between_rotations(matrix_from_quat(held), matrix_from_quat(yaw_quat(yaw)))


def _inconsistent(detail: str) -> Infeasibility:
    return Infeasibility("inconsistent", detail)


def check_consistency(
    sim: Sim,
    problem: ProblemSpec,
    state: State,
    action: Action,
    handle_target: Callable[[str, tuple[float, float, float]], Pose3],
) -> Infeasibility | None:
    """None if ``action``'s parameters fit ``state``; else what does not (see the module doc).

    ``handle_target`` gives a door's handle grasp from a standing pose (the samplers' own).
    """
    params, discrete = action.params, action.discrete
    corners = params.base_path.corners
    if not _same_pose(corners[0], state.robot.base):
        return _inconsistent(
            f"the base path starts at {_fmt(corners[0])}, not where the robot stands "
            f"{_fmt(state.robot.base)}"
        )
    first = params.arm_waypoints[0]
    if not _same_conf(first, state.robot.joints):
        return _inconsistent(
            f"the arm motion starts at {_fmt(first)}, not at the configuration the robot holds "
            f"{_fmt(state.robot.joints)}"
        )
    stand = corners[-1]
    sim.set_state(state)
    if isinstance(discrete, Pick) and isinstance(params, PickParams):
        if not state.has_pose(discrete.obj):
            return _inconsistent(f"'{discrete.obj}' is not resting anywhere")
        pose = state.pose(discrete.obj)
        region = supporting_region(problem, pose)
        if region is None:
            return _inconsistent(f"'{discrete.obj}' rests on no region")
        expected: list[tuple[float, float, float]] = [problem.region(region).base_pose]
        what = f"the standing pose of '{region}'"
    elif isinstance(discrete, Place) and isinstance(params, PlaceParams):
        if discrete.direction == "on":
            region = discrete.ref
        elif state.has_pose(discrete.ref):
            region = supporting_region(problem, state.pose(discrete.ref)) or ""
        else:
            return _inconsistent(f"'{discrete.ref}' is not resting anywhere")
        if not region:
            return _inconsistent(f"'{discrete.ref}' rests on no region")
        expected = [problem.region(region).base_pose]
        what = f"the standing pose of '{region}'"
    elif isinstance(discrete, Open) and isinstance(params, OpenParams):
        expected = list(problem.door(discrete.door).base_poses)
        what = f"a standing pose of '{discrete.door}'"
    else:
        return _inconsistent(f"the parameters are not those of {discrete}")
    if not any(_same_pose(stand, pose) for pose in expected):
        return _inconsistent(f"the base path ends at {_fmt(stand)}, not at {what}")
    if isinstance(params, PickParams):
        hand = _hand_at(sim, stand, params.grasp_conf)
        held, held_orientation = compose(hand, params.grasp.pose)
        assert isinstance(discrete, Pick)
        target = state.pose(discrete.obj)
        gap = math.dist(held, (target.x, target.y, target.z))
        if not gap <= REACH_TOLERANCE:  # NaN is no reach either
            return _inconsistent(
                f"the saved grasp holds '{discrete.obj}' {gap:.2f} m from where it stands"
            )
        turn = _turn(held_orientation, target.yaw)
        if not turn <= TURN_TOLERANCE:
            return _inconsistent(
                f"the saved grasp holds '{discrete.obj}' turned {turn:.2f} rad from how it stands"
            )
    elif isinstance(params, PlaceParams):
        if state.held is None:
            return _inconsistent("the hand is empty")
        hand = _hand_at(sim, stand, params.place_conf)
        carried, carried_orientation = compose(hand, state.held.pose)
        placement = params.placement
        gap = math.dist(carried, (placement.x, placement.y, placement.z))
        assert isinstance(discrete, Place)
        if not gap <= REACH_TOLERANCE:
            return _inconsistent(
                f"the hand at the place configuration holds '{discrete.obj}' {gap:.2f} m from "
                f"its saved placement {discrete.direction} '{discrete.ref}'"
            )
        turn = _turn(carried_orientation, placement.yaw)
        if not turn <= TURN_TOLERANCE:
            return _inconsistent(
                f"the hand at the place configuration holds '{discrete.obj}' turned {turn:.2f} "
                f"rad from its saved placement {discrete.direction} '{discrete.ref}'"
            )
    else:
        assert isinstance(params, OpenParams) and isinstance(discrete, Open)
        hand = _hand_at(sim, stand, params.handle_conf)
        handle = handle_target(discrete.door, stand)
        gap = math.dist(hand[0], handle[0])
        if not gap <= REACH_TOLERANCE:
            return _inconsistent(f"the hand is {gap:.2f} m from the handle of '{discrete.door}'")
    return None


def check_outcome(
    sim: Sim, problem: ProblemSpec, after: State, action: Action
) -> Infeasibility | None:
    """None if the state ``action`` produced is sound: the arm motion ends in the configuration
    the robot then holds, a placed object rests where the action says, penetrating nothing; an
    opened door swings through no object."""
    discrete = action.discrete
    last = action.params.arm_waypoints[-1]
    if not _same_conf(last, after.robot.joints):
        return _inconsistent(
            f"the arm motion ends at {_fmt(last)}, not at the configuration the robot then "
            f"holds {_fmt(after.robot.joints)}"
        )
    sim.set_state(after)
    if isinstance(discrete, Place):
        if not at_position(problem, after, discrete.obj, discrete.direction, discrete.ref):
            return _inconsistent(
                f"the saved placement does not put '{discrete.obj}' {discrete.direction} "
                f"'{discrete.ref}'"
            )
        body = sim.bodies.objects[discrete.obj]
        hits = sim.contacts_of([body])
        if hits:
            names = tuple(sorted(sim.bodies.name_of(b) for b in hits))
            return Infeasibility(
                "no_placement", f"the saved placement of '{discrete.obj}' penetrates", names
            )
    elif isinstance(discrete, Open):
        door = sim.bodies.doors[discrete.door]
        hits = {b for b in sim.contacts_of([door]) if not sim.is_static(b)}
        if hits:
            names = tuple(sorted(sim.bodies.name_of(b) for b in hits))
            return Infeasibility("door_blocked", f"'{discrete.door}' swings into", names)
    return None


def _fmt(pose: tuple[float, ...]) -> str:
    return "(" + ", ".join(f"{v:.2f}" for v in pose) + ")"
