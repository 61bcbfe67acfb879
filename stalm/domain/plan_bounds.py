"""The numbers of a saved action, bounded by the world before anything is built from them.

A plan file is not ours, and a number the robot cannot have is worse than wrong. A grasp
orientation of (1e300, 1e300, 0, 0) composes to NaN, and PyBullet reports no contact for a body
at a NaN pose, so the held object's collisions would go unchecked; a joint at 2*pi is
collision-free and still beyond what the Panda can turn; a joint of 1e5 rad or a base corner
1e7 m away makes the dense motion millions of configurations long, and memory runs out before
the first of them is swept. So, before any motion is densified, every base corner and
placement lies on the problem's floor, every angle within what a problem file may hold, every
configuration within the robot's limits, every quaternion is a unit one, a grasp holds the
object within its own size, and the length of each dense motion is counted from its waypoints
and bounded.

The planner's own actions pass by construction: IK clamps the joints to their limits and the
lift to its range, roadmap corners and standing poses lie on the floor, grasps are taken at
points of the object. The bounds on the dense motions are far above any plan's (a few hundred
poses and configurations an action in every committed result).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from stalm.domain.params import Action, PickParams, PlaceParams
from stalm.motion.arm_motion import interpolated_length
from stalm.motion.base_motion import BasePath, densified_length
from stalm.world.robot_description import Robot
from stalm.world.spec import ProblemSpec
from stalm.world.spec_values import MAX_EXTENT

SWEEP_RESOLUTION = 0.05
"""Spacing (m) of the poses at which a replay sweeps a base path (the base planner's own)."""
MAX_BASE_POSES = 100_000
"""Poses a replay sweeps along one base path at most: a 5 km path (a plan's longest is some
20 m), a few seconds of collision checks."""
MAX_ARM_CONFIGURATIONS = 20_000
"""Configurations a replay sweeps along one action's arm motion at most (a plan's use about
300; the joints' whole ranges take under 200 per waypoint)."""
UNIT_TOLERANCE = 1e-6
"""How far from 1 a grasp quaternion's norm may be (stored ones are within 1e-9)."""
LIMIT_TOLERANCE = 1e-9
"""How far (m, rad) a configuration may lie outside the limits: rounding, no more."""
GRASP_MARGIN = 0.05
"""How far (m) beyond the object's bounding box a grasp point may lie (a plate is held just
above its rim)."""


def out_of_bounds(spec: ProblemSpec, robot: Robot, action: Action) -> str | None:
    """None if every number of ``action`` is one ``robot`` in ``spec``'s world can have and
    its dense motions are of a size a replay can sweep; else the first that is not, naming
    the field as the plan file does."""
    params = action.params
    corners = params.base_path.corners
    for index, (x, y, yaw) in enumerate(corners):
        why = _off_floor(spec, x, y, f"base_path[{index}]") or _angle(yaw, f"base_path[{index}]")
        if why:
            return why
    for index, conf in enumerate(params.arm_waypoints):
        if why := _beyond_limits(robot, conf, f"arm_waypoints[{index}]"):
            return why
    if isinstance(params, PickParams):
        why = _angle(params.pitch, "pitch") or _angle(params.yaw, "yaw")
        why = why or _beyond_limits(robot, params.grasp_conf, "grasp_conf")
        why = why or _grasp_failure(spec, action.discrete.as_tuple()[1], params)
    elif isinstance(params, PlaceParams):
        placement = params.placement
        why = _off_floor(spec, placement.x, placement.y, "placement")  # its yaw is wrapped
        if why is None and not 0.0 <= placement.z <= MAX_EXTENT:
            why = f"'placement' height {placement.z:g} m is not between 0 and {MAX_EXTENT:g}"
        why = why or _beyond_limits(robot, params.place_conf, "place_conf")
    else:
        why = _beyond_limits(robot, params.handle_conf, "handle_conf")
    return why or _too_long(params.base_path, params.arm_waypoints)


def _off_floor(spec: ProblemSpec, x: float, y: float, what: str) -> str | None:
    (x0, y0), (x1, y1) = spec.floor
    if x0 <= x <= x1 and y0 <= y <= y1:
        return None
    return f"'{what}' ({x:g}, {y:g}) is off the floor {spec.floor}"


def _angle(value: float, what: str) -> str | None:
    if abs(value) <= MAX_EXTENT:
        return None
    return f"'{what}' angle {value:g} rad is beyond +-{MAX_EXTENT:g}, what a problem may hold"


def _beyond_limits(robot: Robot, conf: Sequence[float], what: str) -> str | None:
    """Why the lift or a joint of ``conf`` lies outside ``robot``'s limits, if one does."""
    if len(conf) != 1 + len(robot.joint_limits):
        return (
            f"'{what}' has {len(conf)} numbers: {robot.name}'s configuration is the lift and "
            f"{len(robot.joint_limits)} joints"
        )
    low, high = robot.platform.lift_range
    if not low - LIMIT_TOLERANCE <= conf[0] <= high + LIMIT_TOLERANCE:
        return f"'{what}' lift {conf[0]:g} m is outside its range [{low:g}, {high:g}]"
    joints = zip(conf[1:], robot.joint_limits, strict=True)
    for joint, (value, (low, high)) in enumerate(joints, start=1):
        if not low - LIMIT_TOLERANCE <= value <= high + LIMIT_TOLERANCE:
            return (
                f"'{what}' joint {joint} is {value:g} rad, outside its limits [{low:g}, {high:g}]"
            )
    return None


def _grasp_failure(spec: ProblemSpec, obj: str, params: PickParams) -> str | None:
    """Why the grasp is no pose of a gripper holding ``obj``: not a rotation, or the object's
    frame farther from the grasp point than the object's size allows."""
    norm = math.hypot(*params.grasp.orientation)
    if not abs(norm - 1.0) <= UNIT_TOLERANCE:
        return f"'grasp.orientation' is not a unit quaternion (its norm is {norm:g})"
    if obj not in {o.name for o in spec.objects}:
        return None  # no object to hold: the step's precondition says so
    hx, hy, hz = spec.object(obj).half_extents
    reach = math.hypot(hx, hy, 2 * hz) + GRASP_MARGIN
    distance = math.hypot(*params.grasp.position)
    if not distance <= reach:
        return (
            f"'grasp.position' holds '{obj}' {distance:.2f} m from the grasp point, beyond its "
            f"size ({reach:.2f} m)"
        )
    return None


def _too_long(path: BasePath, waypoints: Sequence[Sequence[float]]) -> str | None:
    """Why a dense motion of the action would be too long to sweep, counted before it is made."""
    poses = densified_length(path, SWEEP_RESOLUTION)
    if poses > MAX_BASE_POSES:
        return (
            f"the base path would be swept at {poses:.0f} poses, more than the "
            f"{MAX_BASE_POSES} a replay sweeps"
        )
    confs = interpolated_length(waypoints)
    if confs > MAX_ARM_CONFIGURATIONS:
        return (
            f"the arm motion would be swept at {confs} configurations, more than the "
            f"{MAX_ARM_CONFIGURATIONS} a replay sweeps"
        )
    return None
