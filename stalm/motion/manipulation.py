"""PICK's, PLACE's and OPEN's motions at a standing pose, built once for every user.

The operators' samplers ψ (``stalm.domain``), the occlusion predicates (``stalm.predicates``)
and PDDLStream's streams (``stalm.planners.pddlstream``) must plan the very same motions, or a
predicate would call feasible what PICK then cannot do. Each builds its motions here:

* :meth:`Manipulator.picks`, :meth:`Manipulator.places` and :meth:`Manipulator.open`: IK for
  the gripper's target (with the operator's restarts), then the arm's waypoints into that
  configuration and out of it (:mod:`stalm.motion.reach`), as one :class:`ArmMotion`, and
  for a pick or a placement another one at the next lift height while the caller refuses
  them (the first's motion collides);
* :meth:`ArmMotion.pick_segments` and its kin: the dense motion as the segments a sweep tests
  (:mod:`stalm.motion.sweeps`), carrying the object where the operator carries it;
* :meth:`Manipulator.sweep`: that motion swept through the scene, refused if it touches the
  static scene (walls, furniture), since no moving of objects frees it;
* :func:`route_segment`: the base's roadmap route to a standing pose.

What each user checks differs by design and stays with it: the samplers stop at the first
collision with anything (a feasible κ), the predicates and streams record every movable a
motion touches (occluders).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from stalm.geometry.transforms import (
    Pose3,
    compose,
    gripper_rotation,
    invert,
    quat_from_matrix,
    se2_to_local,
    se2_to_world,
    wrap_angle,
    yaw_quat,
)
from stalm.motion.arm_motion import interpolate_waypoints
from stalm.motion.base_motion import BasePath, BasePlanner
from stalm.motion.colliders import make_collider
from stalm.motion.grasps import APPROACH_DISTANCE, LIFT_DISTANCE, PLACE_CLEARANCE
from stalm.motion.ik import solutions_by_lift, solve_ik
from stalm.motion.reach import leave_waypoints, reach_waypoints, solution_conf
from stalm.motion.sweeps import ArmSegment, BaseSegment, ObjectAt, Segment, SweptMotion, sweep
from stalm.motion.sweeps import base_segment as _base_segment
from stalm.world import robot as robot_model
from stalm.world.scene import Sim
from stalm.world.spec import DoorSpec
from stalm.world.state import Grasp, ObjectPose

Conf = tuple[float, ...]
SE2 = tuple[float, float, float]

PARKED = ObjectPose(0.0, 0.0, -20.0, 0.0)
"""Where an object's body waits while it is out of the scene (far below the floor)."""

OPEN_IK_FACTOR = 3
"""OPEN's IK gets this many times the operator's restarts: the handle's pose is fixed, so
there is no other grasp to draw when IK misses it."""


@dataclass(frozen=True)
class ArmMotion:
    """An arm motion at one standing pose into ``key_conf`` and out of it.

    For PICK ``into`` is the approach and ``out`` the lift with the object; for PLACE the
    lowering with the object and the retreat; for OPEN the unfolding to the handle and the
    folding back. ``into`` ends and ``out`` starts at ``key_conf``.
    """

    stand: SE2
    key_conf: Conf
    into: tuple[Conf, ...]
    out: tuple[Conf, ...]

    @property
    def waypoints(self) -> tuple[Conf, ...]:
        """The whole motion's waypoints, ``key_conf`` once."""
        return (*self.into, *self.out[1:])

    def pick_segments(self, obj: str, grasp: Grasp) -> tuple[Segment, ...]:
        """Reaching ``obj`` (which is then no obstacle), then lifting it held at ``grasp``."""
        return (
            ArmSegment(self.stand, _dense(self.into), None, obj),
            ArmSegment(self.stand, _dense(self.out), grasp, None),
        )

    def place_segments(self, obj: str, grasp: Grasp, pose: ObjectPose) -> tuple[Segment, ...]:
        """Lowering ``obj`` held at ``grasp``, the object standing at ``pose``, the retreat."""
        return (
            ArmSegment(self.stand, _dense(self.into), grasp, None),
            ObjectAt(obj, pose),
            ArmSegment(self.stand, _dense(self.out), None, obj),
        )

    def open_segments(self) -> tuple[Segment, ...]:
        """The empty hand's reach to the handle and back."""
        return (ArmSegment(self.stand, _dense(self.waypoints), None, None),)


class Manipulator:
    """Builds and sweeps pick, place and open motions in one simulator (which it moves)."""

    def __init__(self, sim: Sim, engine: str = "batched") -> None:
        self.sim = sim
        self.collider = make_collider(sim, engine)
        """What the motions touch (the batched engine, or the PyBullet reference)."""
        self.spec = sim.problem
        self.static = frozenset(sim.bodies.walls.values()) | frozenset(sim.bodies.regions.values())
        """Bodies no action moves: a motion touching one is infeasible, not occluded."""
        self.extent = {
            o.name: math.hypot(o.half_extents[0], o.half_extents[1]) for o in self.spec.objects
        }
        """Each object's radius seen from above."""

    def picks(
        self, stand: SE2, target: Pose3, rng: np.random.Generator, ik_attempts: int
    ) -> Iterator[ArmMotion]:
        """The gripper at ``target``: IK, the approach backing off along the gripper's axis,
        and the lift; one motion per lift height IK reaches it from (see
        :func:`~stalm.motion.ik.solutions_by_lift`), the next asked for only when the caller
        refuses one. Nothing stays attached."""
        return self._reaches(
            stand, target, rng, ik_attempts, (APPROACH_DISTANCE, 0.0), (0.0, LIFT_DISTANCE)
        )

    def places(
        self, stand: SE2, hand: Pose3, rng: np.random.Generator, ik_attempts: int
    ) -> Iterator[ArmMotion]:
        """The hand at ``hand`` (see :func:`placing_hand`): IK, the lowering from above, and
        the retreat along the gripper's axis; one motion per lift height, as :meth:`picks`."""
        return self._reaches(
            stand, hand, rng, ik_attempts, (0.0, PLACE_CLEARANCE), (APPROACH_DISTANCE, 0.0)
        )

    def _reaches(
        self,
        stand: SE2,
        target: Pose3,
        rng: np.random.Generator,
        ik_attempts: int,
        into: tuple[float, float],
        out: tuple[float, float],
    ) -> Iterator[ArmMotion]:
        """IK at ``target``, then waypoints in through and out through offset poses, each
        (backoff along the gripper's axis, raise) from the target."""
        self.sim.attach(None)
        for solution in solutions_by_lift(self.sim, stand, target, rng, ik_attempts):
            yield ArmMotion(
                stand,
                solution_conf(solution),
                tuple(reach_waypoints(self.sim, stand, target, solution, *into)),
                tuple(leave_waypoints(self.sim, stand, target, solution, *out)),
            )

    def open(
        self, door: str, stand: SE2, rng: np.random.Generator, ik_attempts: int
    ) -> ArmMotion | None:
        """The hand at ``door``'s handle from ``stand``: IK with :data:`OPEN_IK_FACTOR` times
        the restarts, unfolding to it and folding back; None if IK finds no solution."""
        target = handle_target(self.spec.door(door), stand)
        solution = solve_ik(self.sim, stand, target, rng, ik_attempts * OPEN_IK_FACTOR)
        if solution is None:
            return None
        handle = solution_conf(solution)
        return ArmMotion(
            stand,
            handle,
            (*robot_model.unfold(handle, self.sim.robot.carry_conf), handle),
            (handle, *robot_model.fold(handle, self.sim.robot.carry_conf)),
        )

    def sweep(
        self, segments: tuple[Segment, ...], refuse: frozenset[int] = frozenset()
    ) -> tuple[SweptMotion, frozenset[int]] | None:
        """Sweep ``segments`` in the world as the caller set it: None if they touch the static
        scene or a body of ``refuse``, else the motion (with no hits named yet) and every body
        it touched. A refused motion is not swept past the contact that refuses it."""
        stop = self.static | refuse
        bodies, fan = sweep(self.collider, segments, stop)
        if bodies & stop:
            return None
        held = next((s.held for s in segments if isinstance(s, ArmSegment) and s.held), None)
        reach = self.extent[held.obj] + math.dist((0, 0, 0), held.position) if held else 0.0
        return SweptMotion(segments, frozenset(), fan, reach), bodies


def placing_hand(placement: ObjectPose, grasp: Grasp) -> Pose3:
    """The gripper pose that puts an object held at ``grasp`` down at ``placement``."""
    object_pose: Pose3 = ((placement.x, placement.y, placement.z), yaw_quat(placement.yaw))
    return compose(object_pose, invert(grasp.pose))


def handle_target(door: DoorSpec, stand: SE2) -> Pose3:
    """The door's fixed handle grasp on the robot's side: horizontal, facing the panel."""
    _, sv = se2_to_local((*door.hinge, door.closed_yaw), stand[0], stand[1])
    side = 1.0 if sv > 0 else -1.0
    reach = door.thickness / 2 + 0.05 - 0.015
    x, y = se2_to_world((*door.hinge, door.closed_yaw), door.handle_distance, side * reach)
    approach = wrap_angle(door.closed_yaw - side * math.pi / 2)
    return (x, y, door.handle_height), quat_from_matrix(gripper_rotation(approach, 0.0))


def route_segment(
    planner: BasePlanner, start: SE2, goal: SE2, open_doors: frozenset[str]
) -> BaseSegment:
    """The base's roadmap route from ``start`` to ``goal`` with ``open_doors`` open, densified
    (the straight line when the roadmap has none), keeping ``start``'s heading in between."""
    nodes = planner.route(start, goal, open_doors)
    corners: tuple[SE2, ...] = (start, goal)
    if nodes is not None:
        roadmap = planner.roadmap(open_doors)
        inner = tuple(
            (float(roadmap.nodes[n][0]), float(roadmap.nodes[n][1]), start[2]) for n in nodes[1:-1]
        )
        corners = (start, *inner, goal)
    return _base_segment(BasePath(corners), planner.resolution)


def _dense(waypoints: tuple[Conf, ...]) -> tuple[Conf, ...]:
    return tuple(interpolate_waypoints(waypoints))
