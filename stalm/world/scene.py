"""The PyBullet scene of one problem: setting it from a State, and the queries the planner makes.

One :class:`Sim` owns one DIRECT client; its bodies are built once by
:func:`stalm.world.scene_build.build_bodies`. The world is set kinematically from a
:class:`~stalm.world.state.State` and queried; physics is never stepped. Movable objects and
the robot are given mass so Bullet's broadphase reports their contacts with the static scene
(static-static pairs are never tested), which makes one ``performCollisionDetection`` call
answer "what touches the robot?" for the whole world. Bodies that ever move (objects, doors,
the robot) must be non-static for another reason too: Bullet refreshes broadphase bounds only
of non-static bodies, so a static body moved by a reset would be tested at its old place.

A query only asks what touches some bodies, yet a plain ``performCollisionDetection`` also
computes every other contact in the world: each object resting on its table, side by side
with its neighbours, a door in its frame. :meth:`Sim.contacts_of` therefore first sets the
collision filter masks so that only pairs with one of the queried bodies are tested (the
contacts reported for those bodies are the same); on a crowded table this makes a query about
three times cheaper.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence

import pybullet as p

from stalm.errors import StalmError
from stalm.geometry.transforms import Pose3, quat_yaw, yaw_quat
from stalm.world import robot as robot_model
from stalm.world.robot_loader import robot_named
from stalm.world.robot_stance import fixed_base_mismatch
from stalm.world.scene_build import build_bodies
from stalm.world.spec import ProblemSpec
from stalm.world.state import Grasp, ObjectPose, RobotConf, State

QUERIED_GROUP = 2
"""Collision filter group of the bodies a query asks about; they collide with the rest only."""
REST_GROUP = 1
"""Collision filter group of every other body; they collide with the queried bodies only."""

PENETRATION_TOLERANCE = 1e-3
"""Contacts shallower than this (m) are touching, not colliding: objects resting on a surface
or standing side by side are legal."""


def _penetrates(body: int, other: int, client: int) -> bool:
    """Does ``body`` penetrate ``other`` deeper than the tolerance, by their closest points
    (computed afresh: no contact manifold kept from earlier queries)?"""
    points = p.getClosestPoints(body, other, 0.0, physicsClientId=client)
    return any(point[8] < -PENETRATION_TOLERANCE for point in points)


class Sim:
    """A PyBullet DIRECT client holding one problem's scene.

    The scene's static part (walls, regions) never moves; doors, objects and the robot are set
    from a State with :meth:`set_state`. Counters of collision checks are kept for benchmarks.
    """

    def __init__(self, problem: ProblemSpec, stop: Callable[[], bool] | None = None) -> None:
        """The scene of ``problem``; ``stop`` (see :func:`build_bodies`) may cut building short
        with :exc:`~stalm.world.scene_build.SceneAbandoned`, the client then closed."""
        self.problem = problem
        self.robot = robot_named(problem.robot.robot)
        """The robot the problem names, as its robot file describes it."""
        why = fixed_base_mismatch(problem, self.robot)
        if why is not None:
            raise StalmError(why)
        self.client = p.connect(p.DIRECT)
        try:
            self.bodies = build_bodies(self.client, problem, self.robot, stop)
        except BaseException:
            p.disconnect(self.client)
            raise
        self.collision_checks = 0
        self._held: Grasp | None = None
        self._held_yaw_offset = 0.0
        self._gripper: Pose3 | None = None
        """The grasp point's world pose in the arm's current configuration, once asked for."""
        carry = self.robot.carry_conf
        self._robot = RobotConf.make((0.0, 0.0, 0.0), carry[0], carry[1:])
        self._mount_forward = self.robot.platform.arm_mount_forward
        self._arm_joints = list(self.bodies.joints.arm)
        self._static_ids = frozenset(self.bodies.walls.values()) | frozenset(
            self.bodies.regions.values()
        )
        self._object_by_body = {bid: name for name, bid in self.bodies.objects.items()}
        self._door_by_body = {bid: name for name, bid in self.bodies.doors.items()}
        self._links = {
            body: tuple(range(-1, p.getNumJoints(body, physicsClientId=self.client)))
            for body in range(p.getNumBodies(physicsClientId=self.client))
        }
        """Every body's link indices (-1 is the base), for setting collision masks."""
        self._queried: frozenset[int] | None = None
        """The bodies the collision masks are set to test (None: masks not set yet)."""

    # ------------------------------------------------------------------ state
    def set_state(self, state: State) -> None:
        """Place every body as ``state`` says (objects, doors, robot, held object)."""
        c = self.client
        for name, pose in state.poses:
            p.resetBasePositionAndOrientation(
                self.bodies.objects[name],
                [pose.x, pose.y, pose.z],
                yaw_quat(pose.yaw),
                physicsClientId=c,
            )
        for door in self.problem.doors:
            self.set_door(door.name, state.is_open(door.name))
        self._held = state.held
        self._held_yaw_offset = state.held_yaw_offset
        self.set_robot(state.robot)

    def read_state(self) -> State:
        """The State the simulator shows now (inverse of :meth:`set_state`)."""
        c = self.client
        held = self._held.obj if self._held is not None else None
        poses = []
        for name, body in self.bodies.objects.items():
            if name == held:
                continue
            pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=c)
            poses.append((name, ObjectPose.make(pos[0], pos[1], pos[2], quat_yaw(orn))))
        open_doors = frozenset(d.name for d in self.problem.doors if self.door_is_open(d.name))
        return State(
            poses=tuple(sorted(poses)),
            open_doors=open_doors,
            robot=self.read_robot(),
            held=self._held,
            held_yaw_offset=self._held_yaw_offset,
        )

    def set_door(self, name: str, is_open: bool) -> None:
        door = self.problem.door(name)
        self.set_door_angle(name, door.open_yaw if is_open else door.closed_yaw)

    def set_door_angle(self, name: str, yaw: float) -> None:
        door = self.problem.door(name)
        p.resetBasePositionAndOrientation(
            self.bodies.doors[name],
            [door.hinge[0], door.hinge[1], 0.0],
            yaw_quat(yaw),
            physicsClientId=self.client,
        )

    def door_is_open(self, name: str) -> bool:
        door = self.problem.door(name)
        _, orn = p.getBasePositionAndOrientation(
            self.bodies.doors[name], physicsClientId=self.client
        )
        yaw = quat_yaw(orn)
        return abs(math.remainder(yaw - door.open_yaw, math.tau)) < abs(
            math.remainder(yaw - door.closed_yaw, math.tau)
        )

    def set_robot(self, conf: RobotConf) -> None:
        """Place base, lift and arm; the held object (if any) follows the hand."""
        c = self.client
        x, y, yaw = conf.base
        p.resetBasePositionAndOrientation(
            self.bodies.base, [x, y, 0.0], yaw_quat(yaw), physicsClientId=c
        )
        self.set_arm(conf.base, conf.lift, conf.arm)
        self._robot = conf

    def arm_mount(self, base: tuple[float, float, float], lift: float) -> robot_model.ArmMount:
        """Where the arm's base sits for a base pose and a lift height."""
        return robot_model.arm_mount(base, lift, self._mount_forward)

    def set_arm(self, base: tuple[float, float, float], lift: float, arm: Sequence[float]) -> None:
        self.set_arm_at(self.arm_mount(base, lift), arm)

    def set_arm_at(self, mount: robot_model.ArmMount, arm: Sequence[float]) -> None:
        """:meth:`set_arm` with the arm's mount already computed (a sweep needs it anyway)."""
        c = self.client
        p.resetBasePositionAndOrientation(
            self.bodies.arm, [mount.x, mount.y, mount.z], yaw_quat(mount.yaw), physicsClientId=c
        )
        # one call for all the joints: five times faster than a resetJointState call each
        p.resetJointStatesMultiDof(
            self.bodies.arm, self._arm_joints, [[value] for value in arm], physicsClientId=c
        )
        self._gripper = None
        if self._held is not None:
            self._place_held()

    def set_base_only(self, base: tuple[float, float, float]) -> None:
        """Move base and arm rigidly to ``base`` keeping lift and joints (for base paths)."""
        c = self.client
        x, y, yaw = base
        p.resetBasePositionAndOrientation(
            self.bodies.base, [x, y, 0.0], yaw_quat(yaw), physicsClientId=c
        )
        mount = self.arm_mount(base, self._robot.lift)
        p.resetBasePositionAndOrientation(
            self.bodies.arm, [mount.x, mount.y, mount.z], yaw_quat(mount.yaw), physicsClientId=c
        )
        self._gripper = None
        if self._held is not None:
            self._place_held()

    def read_robot(self) -> RobotConf:
        c = self.client
        pos, orn = p.getBasePositionAndOrientation(self.bodies.base, physicsClientId=c)
        mount_pos, _ = p.getBasePositionAndOrientation(self.bodies.arm, physicsClientId=c)
        arm = [p.getJointState(self.bodies.arm, j, physicsClientId=c)[0] for j in self._arm_joints]
        return RobotConf.make((pos[0], pos[1], quat_yaw(orn)), mount_pos[2], arm)

    def arm_conf(self) -> tuple[float, ...]:
        """The lift and the arm joints as the simulator has them now."""
        states = p.getJointStates(self.bodies.arm, self._arm_joints, physicsClientId=self.client)
        return (self._robot.lift, *(state[0] for state in states))

    def gripper_pose(self) -> Pose3:
        """World pose of the grasp point between the fingertips (computed once per arm
        configuration: a sweep asks for it to carry the held object and again for its
        reach lines)."""
        if self._gripper is None:
            self._gripper = self.bodies.joints.grasp_pose(self.client, self.bodies.arm)
        return self._gripper

    def _place_held(self) -> None:
        assert self._held is not None
        hand_pos, hand_orn = self.gripper_pose()
        pos, orn = p.multiplyTransforms(
            hand_pos,
            hand_orn,
            self._held.position,
            self._held.orientation,
            physicsClientId=self.client,
        )
        p.resetBasePositionAndOrientation(
            self.bodies.objects[self._held.obj], pos, orn, physicsClientId=self.client
        )

    def attach(self, grasp: Grasp | None, yaw_offset: float = 0.0) -> None:
        """Start (or with None, stop) carrying an object at ``grasp``."""
        self._held = grasp
        self._held_yaw_offset = yaw_offset

    @property
    def held(self) -> Grasp | None:
        return self._held

    @property
    def held_yaw_offset(self) -> float:
        return self._held_yaw_offset

    def object_pose(self, name: str) -> Pose3:
        pos, orn = p.getBasePositionAndOrientation(
            self.bodies.objects[name], physicsClientId=self.client
        )
        return (pos[0], pos[1], pos[2]), (orn[0], orn[1], orn[2], orn[3])

    def place_object(self, name: str, pose: ObjectPose) -> None:
        p.resetBasePositionAndOrientation(
            self.bodies.objects[name],
            [pose.x, pose.y, pose.z],
            yaw_quat(pose.yaw),
            physicsClientId=self.client,
        )

    # ------------------------------------------------------------------ collisions
    def robot_bodies(self) -> tuple[int, ...]:
        """The bodies that move with the robot: base, arm and the held object."""
        if self._held is None:
            return (self.bodies.base, self.bodies.arm)
        return (self.bodies.base, self.bodies.arm, self.bodies.objects[self._held.obj])

    def contacts_of(self, bodies: Iterable[int], ignore: Iterable[int] = ()) -> set[int]:
        """Bodies penetrating any of ``bodies`` now (excluding each other and ``ignore``).

        The world's contact manifold finds the pairs that may penetrate; each pair whose
        manifold depth reaches half the tolerance is then decided by the pairwise query of
        :meth:`touches`. Bullet's manifold depths are approximate (they differ from the
        closest points' by some 1e-5 m), so a pair within that of the tolerance could be a
        contact to one query and none to the other; deciding every pair by the same exact
        query makes a contact mean one thing to every caller, whichever query found the
        pair (the batched engine of :mod:`stalm.motion.colliders` confirms with
        :meth:`touches` too)."""
        c = self.client
        self.collision_checks += 1
        group = set(bodies)
        self._query(frozenset(group))
        p.performCollisionDetection(physicsClientId=c)
        skip = group | set(ignore)
        hits: set[int] = set()
        decided: set[tuple[int, int]] = set()
        for body in group:
            for contact in p.getContactPoints(bodyA=body, physicsClientId=c):
                other = contact[2]
                if other in skip or other in hits or (body, other) in decided:
                    continue
                if contact[8] < -PENETRATION_TOLERANCE / 2:
                    decided.add((body, other))
                    if _penetrates(body, other, c):
                        hits.add(other)
        return hits

    def _query(self, bodies: frozenset[int]) -> None:
        """Set the collision masks so that the next ``performCollisionDetection`` tests only
        pairs of one of ``bodies`` with another body (see the module docstring). Only the
        bodies whose role changed since the last query are touched."""
        if bodies == self._queried:
            return
        changed = self._links.keys() if self._queried is None else self._queried ^ bodies
        for body in changed:
            group, mask = (
                (QUERIED_GROUP, REST_GROUP) if body in bodies else (REST_GROUP, QUERIED_GROUP)
            )
            for link in self._links_of(body):
                p.setCollisionFilterGroupMask(body, link, group, mask, physicsClientId=self.client)
        self._queried = bodies

    def _links_of(self, body: int) -> tuple[int, ...]:
        """``body``'s link indices; a body made after the scene (none is queried today) is
        looked up when first met."""
        if body not in self._links:
            joints = p.getNumJoints(body, physicsClientId=self.client)
            self._links[body] = tuple(range(-1, joints))
        return self._links[body]

    def touches(self, bodies: Iterable[int], other: int) -> bool:
        """Does any of ``bodies`` penetrate ``other``? A pairwise query: much cheaper than a
        whole-world :meth:`contacts_of` when only one obstacle matters."""
        self.collision_checks += 1
        return any(_penetrates(body, other, self.client) for body in bodies)

    def robot_contacts(self, ignore: Iterable[int] = ()) -> set[int]:
        """Bodies the robot (with what it holds) penetrates in its current configuration."""
        return self.contacts_of(self.robot_bodies(), ignore)

    def is_static(self, body: int) -> bool:
        return body in self._static_ids

    def object_of(self, body: int) -> str | None:
        return self._object_by_body.get(body)

    def door_of(self, body: int) -> str | None:
        return self._door_by_body.get(body)

    def close(self) -> None:
        if p.isConnected(self.client):
            p.disconnect(self.client)

    def __enter__(self) -> Sim:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()
