"""The streams: ψ's samplers and motion planning, one call at a time, and the collision tests.

PDDLStream's vocabulary for this domain:

* ``sample-grasp(o) -> g``: a gripper pitch and yaw drawn from PICK's ranges (paper §4.1).
* ``sample-pose(o, r) -> p``: a uniform placement on region r's usable area, with the yaw
  PLACE keeps (``(Supported o p r)``).
* ``sample-rel-pose(o, dir, o2, p2) -> p``: placements drawn as PLACE draws them, rejected
  until they lie in ``dir`` of o2 standing at p2 (``(Rel o p dir o2 p2)``).
* ``plan-pick(o, p, g) -> m`` / ``plan-place(o, p, g) -> m``: IK and the arm's reach and leave
  waypoints at the region's standing pose, exactly as PICK and PLACE build them, checked
  against the static scene only (``(PickKin o p g m)`` / ``(PlaceKin o p g m)``).
* ``plan-open(d) -> m``: the door's handle motion from its nearest standing pose.
* Tests: ``Collides(m, o2, p2)`` (the motion, its base route or the door it swings touches o2
  standing at p2) and ``Crosses(m, d)`` (they pass door d's closed panel).

Motions are planned *ignoring movable objects* and then swept against each object at each
pose, as the occlusion predicates do (:mod:`stalm.motion.sweeps`); this is PDDLStream's
"plan the motion ignoring fluents, certify collisions with test streams". The base route to a
standing pose is the roadmap route from the robot's initial pose with every door open (the
predicate engine's convention); the real base path is planned when the action is executed.

One call draws once (one IK problem with the operator's restarts), so a stream instance that
fails can be called again later: PDDLStream streams are generators.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stalm.domain.mdp import Domain
from stalm.geometry.transforms import compose, invert, se2_to_world, wrap_angle, yaw_quat
from stalm.motion.grasps import (
    draw_placement,
    grasp_points,
    grasp_window,
    gripper_target,
    placement_bounds,
    sample_grasp_angles,
    yaw_limited,
)
from stalm.motion.manipulation import PARKED, ArmMotion, Manipulator, placing_hand, route_segment
from stalm.motion.sweeps import Segment, SweptMotion, sweep, sweep_near
from stalm.planners.pddlstream.values import SE2, GraspValue, MotionValue, PoseValue
from stalm.world.grip_widths import too_wide
from stalm.world.relations import direction_between, supporting_region
from stalm.world.state import Grasp, ObjectPose, RobotConf

CANONICAL_DISTANCE = 0.7
"""How far ahead of its standing pose an object is imagined when a grasp is sampled (m)."""


@dataclass(frozen=True)
class Route:
    """The base route from the robot's initial pose to one standing pose."""

    swept: SweptMotion
    crosses: frozenset[str]


class StreamGeometry:
    """The streams' samplers and tests on one domain's simulator (which they reconfigure)."""

    def __init__(self, domain: Domain) -> None:
        self.domain = domain
        self.problem = domain.problem
        self.spec = domain.problem.spec
        self.sim = domain.sim
        self.settings = domain.sampler_settings
        self.start = self.spec.robot.base
        self._routes: dict[SE2, Route] = {}
        self._route_hits: dict[tuple[SE2, str, ObjectPose], bool] = {}
        self.hands = Manipulator(self.sim)
        self._door_of_body = {body: name for name, body in self.sim.bodies.doors.items()}
        self._extent = self.hands.extent
        initial = self.problem.initial_state
        self._yaw_offset: dict[str, float] = {}
        for obj in self.spec.objects:
            pose = initial.pose(obj.name) if initial.has_pose(obj.name) else None
            region = supporting_region(self.spec, pose) if pose is not None else None
            stand_yaw = self.spec.region(region).base_pose[2] if region is not None else 0.0
            yaw = pose.yaw if pose is not None else stand_yaw + initial.held_yaw_offset
            self._yaw_offset[obj.name] = wrap_angle(yaw - stand_yaw)
        self.collision_tests = 0

    # ------------------------------------------------------------------ world
    def _clear(self, stand: SE2) -> None:
        """Every movable parked out of the way, doors closed, the robot folded at ``stand``."""
        self.sim.attach(None)
        for name in self.sim.bodies.objects:
            self.sim.place_object(name, PARKED)
        for door in self.spec.doors:
            self.sim.set_door(door.name, False)
        carry = self.sim.robot.carry_conf
        self.sim.set_robot(RobotConf.make(stand, carry[0], carry[1:]))

    def _motion(
        self,
        kind: str,
        subject: str,
        arm: ArmMotion,
        segments: tuple[Segment, ...],
        names: tuple[str | None, str | None] = (None, None),
        own: str = "",
    ) -> MotionValue | None:
        """``arm``'s motion, swept along ``segments`` in the cleared world: None if they touch
        the static scene; it crosses the doors they and its route pass (``own``, the door
        being opened, excepted)."""
        swept = self.hands.sweep(segments)
        if swept is None:
            return None
        motion, bodies = swept
        doors = frozenset(self._door_of_body[b] for b in bodies if b in self._door_of_body)
        crosses = doors - {own} | self.route(arm.stand).crosses
        return MotionValue(
            kind, subject, arm.stand, motion, arm.waypoints, arm.key_conf, crosses, *names
        )

    def yaw_offset(self, obj: str) -> float:
        """The object's yaw relative to the standing pose it is seen from (PLACE keeps it)."""
        return self._yaw_offset[obj]

    def fits(self, obj: str, region: str) -> bool:
        spec = self.spec.object(obj)
        reg = self.spec.region(region)
        return (
            placement_bounds(spec, reg, wrap_angle(reg.base_pose[2] + self._yaw_offset[obj]))
            is not None
        )

    # ------------------------------------------------------------------ samplers
    def sample_grasp(self, obj: str, rng: np.random.Generator) -> GraspValue | None:
        """Pitch and yaw uniform in PICK's ranges, at the grasp point nearest the robot (a
        box's yaw range cut to where the gripper's opening fits,
        :func:`~stalm.motion.grasps.grasp_window`; None if no grasp fits).

        The object's pose in the gripper frame is computed in a canonical scene (standing
        pose at the origin facing +x, the object 0.7 m ahead with its kept relative yaw):
        every pose of the object relative to its standing pose shares that yaw, so the
        same transform holds at every pose."""
        spec, opening = self.spec.object(obj), self.sim.robot.gripper.opening
        frame = (CANONICAL_DISTANCE, 0.0, self._yaw_offset[obj])
        if too_wide(spec, opening) is not None:
            return None
        if yaw_limited(spec):
            pose = ObjectPose.make(frame[0], frame[1], 0.0, frame[2])
            ranges = self.settings.pitch_range, self.settings.yaw_range
            window = grasp_window(spec, pose, (0.0, 0.0, 0.0), *ranges, gap=opening)
            if window is None:
                return None
            pitch, yaw = sample_grasp_angles(rng, window.pitch_range, window.yaw_range)
            local, point = window.local, window.point
        else:
            pitch, yaw = sample_grasp_angles(
                rng, self.settings.pitch_range, self.settings.yaw_range
            )
            local = min(
                grasp_points(spec), key=lambda q: math.hypot(*se2_to_world(frame, q[0], q[1]))
            )
            point = (*se2_to_world(frame, local[0], local[1]), local[2])
        target = gripper_target(point, 0.0, pitch, yaw)
        relative = compose(invert(target), ((frame[0], 0.0, 0.0), yaw_quat(frame[2])))
        return GraspValue(obj, pitch, yaw, local, Grasp.make(obj, relative[0], relative[1]))

    def sample_pose(self, obj: str, region: str, rng: np.random.Generator) -> PoseValue | None:
        """One uniform placement on ``region``; None if the object does not fit there."""
        reg = self.spec.region(region)
        yaw = wrap_angle(reg.base_pose[2] + self._yaw_offset[obj])
        pose = draw_placement(self.spec.object(obj), reg, yaw, rng)
        return None if pose is None else PoseValue(obj, pose, region)

    def sample_rel_pose(
        self, obj: str, direction: str, ref: PoseValue, rng: np.random.Generator
    ) -> PoseValue | None:
        """Placements on the reference's region, rejected until one lies in ``direction``."""
        reg = self.spec.region(ref.region)
        yaw = wrap_angle(reg.base_pose[2] + self._yaw_offset[obj])
        spec = self.spec.object(obj)
        for _ in range(self.settings.placement_draws):
            pose = draw_placement(spec, reg, yaw, rng)
            if pose is None:
                return None
            if direction_between(reg, pose, ref.pose) == direction:
                return PoseValue(obj, pose, ref.region)
        return None

    # ------------------------------------------------------------------ motions
    def plan_pick(
        self, pose: PoseValue, grasp: GraspValue, names: tuple[str, str], rng: np.random.Generator
    ) -> MotionValue | None:
        """PICK's arm motion for ``grasp`` at ``pose`` (approach, then lift with the object)."""
        obj = pose.obj
        stand = self.spec.region(pose.region).base_pose
        self._clear(stand)
        self.sim.place_object(obj, pose.pose)
        wx, wy = se2_to_world(
            (pose.pose.x, pose.pose.y, pose.pose.yaw), grasp.point[0], grasp.point[1]
        )
        target = gripper_target(
            (wx, wy, pose.pose.z + grasp.point[2]), stand[2], grasp.pitch, grasp.yaw
        )
        for arm in self.hands.picks(stand, target, rng, self.settings.ik_attempts):
            self.sim.place_object(obj, pose.pose)
            value = self._motion("pick", obj, arm, arm.pick_segments(obj, grasp.grasp), names)
            if value is not None:
                return value
        return None

    def plan_place(
        self, pose: PoseValue, grasp: GraspValue, names: tuple[str, str], rng: np.random.Generator
    ) -> MotionValue | None:
        """PLACE's arm motion putting the object held by ``grasp`` down at ``pose``."""
        obj = pose.obj
        stand = self.spec.region(pose.region).base_pose
        self._clear(stand)
        hand = placing_hand(pose.pose, grasp.grasp)
        for arm in self.hands.places(stand, hand, rng, self.settings.ik_attempts):
            segments = arm.place_segments(obj, grasp.grasp, pose.pose)
            value = self._motion("place", obj, arm, segments, names)
            if value is not None:
                return value
        return None

    def plan_open(self, door: str, rng: np.random.Generator) -> MotionValue | None:
        """OPEN's handle motion from the first standing pose (nearest the robot's start) at
        which IK and the arm motion succeed."""
        spec = self.spec.door(door)
        stands = sorted(spec.base_poses, key=lambda s: math.dist(s[:2], self.start[:2]))
        for stand in stands:
            self._clear(stand)
            arm = self.hands.open(door, stand, rng, self.settings.ik_attempts)
            if arm is None:
                continue
            value = self._motion("open", door, arm, arm.open_segments(), own=door)
            if value is not None:
                return value
        return None

    # ------------------------------------------------------------------ tests
    def route(self, stand: SE2) -> Route:
        """The roadmap route from the initial pose to ``stand`` with every door open, and the
        doors whose closed panels it passes (computed once per standing pose)."""
        if stand not in self._routes:
            every_door = frozenset(d.name for d in self.spec.doors)
            segment = route_segment(self.domain.base_planner, self.start, stand, every_door)
            self._clear(self.start)
            bodies, _ = sweep(self.hands.collider, (segment,))
            doors = frozenset(self._door_of_body[b] for b in bodies if b in self._door_of_body)
            self._routes[stand] = Route(SweptMotion((segment,), frozenset()), doors)
        return self._routes[stand]

    def collides(self, motion: MotionValue, pose: PoseValue) -> bool:
        """Does ``motion`` (its base route, its arm sweep, or the door it opens) touch
        ``pose.obj`` standing at ``pose``? Other movables are parked meanwhile."""
        body = self.sim.bodies.objects[pose.obj]
        x, y, radius = pose.pose.x, pose.pose.y, self._extent[pose.obj]
        key = (motion.stand, pose.obj, pose.pose)
        if key not in self._route_hits:
            route = self.route(motion.stand).swept
            hit = False
            if route.near(x, y, radius):
                self._clear(self.start)
                self.sim.place_object(pose.obj, pose.pose)
                self.collision_tests += 1
                hit = sweep_near(self.hands.collider, route, body, x, y, radius)
            self._route_hits[key] = hit
        if self._route_hits[key]:
            return True
        if motion.swept.near(x, y, radius):
            self._clear(motion.stand)
            self.sim.place_object(pose.obj, pose.pose)
            self.collision_tests += 1
            if sweep_near(self.hands.collider, motion.swept, body, x, y, radius):
                return True
        if motion.kind == "open":
            door = self.sim.bodies.doors[motion.subject]
            self._clear(motion.stand)
            self.sim.place_object(pose.obj, pose.pose)
            self.sim.set_door(motion.subject, True)
            self.collision_tests += 1
            hit = self.sim.touches([door], body)
            self.sim.set_door(motion.subject, False)
            return hit
        return False
