"""A physics check of an executed plan: do the objects stay where the plan puts them?

Plans are kinematic: an object placed is assumed to rest where it was put. This module runs
the plan's executed states under PyBullet's dynamics in a client of its own (DIRECT), built
from the problem's spec with the planner's own shapes (:func:`~stalm.world.scene_build.
build_bodies`, :func:`~stalm.world.scene_build.object_shapes`), gravity on:

- every movable object is dynamic, with a mass (:func:`object_mass`) at the centroid of its shape
  (the planner's bodies keep theirs at the bottom face, which would make everything stable);
  walls, regions, doors and the robot's base are fixed, and the arm (a fixed-base body) is
  held in each configuration by PyBullet's default joint motors;
- the robot is set kinematically to each executed state (its motions are swept for collisions
  by the replay, not simulated), and the held object is pinned at the hand's grasp pose by a
  ``JOINT_FIXED`` constraint to the world: the hand does not move while the world settles, and
  pinning it to the world rather than to the hand's link keeps the arm's joint motors out of
  the check (a sagging arm is not what it measures); its contacts with the hand are off;
- after each action (and once for the initial state) the world is stepped for
  :data:`SETTLE_SECONDS`; a PLACE first releases the object at its planned pose. Objects are
  never put back: a drift carries over to the next step, as it would on a real robot.

Each step then measures every resting object's displacement from its pose in the plan:
the distance of its frame origin (m) and its tilt, the angle of its axis from the vertical
(degrees; the plan keeps objects upright, and a spin about the axis moves nothing). Beyond
:data:`TOLERANCE_M` or :data:`TOLERANCE_DEG` the step fails, naming the object.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import pybullet as p

from stalm.errors import StalmError
from stalm.geometry.transforms import yaw_quat
from stalm.world import robot as robot_model
from stalm.world.mesh_pieces import object_pieces, pieces_volume_centroid
from stalm.world.object_spec import GRILL_HANDLE_HALF_HEIGHT, GRILL_HANDLE_REACH, ObjectSpec
from stalm.world.problem import Problem
from stalm.world.robot_loader import robot_named
from stalm.world.scene_build import build_bodies, object_shapes
from stalm.world.state import ObjectPose, State

GRAVITY = -9.81
"""m/s², along -z."""
TIME_STEP = 1.0 / 240.0
"""PyBullet's default step (s); contacts of centimetre objects are stable at it."""
SETTLE_SECONDS = 1.0
"""How long the world is stepped after each action before objects are measured (s)."""
TOLERANCE_M = 0.01
"""An object whose frame moved further than this from the plan's pose fails the check (m)."""
TOLERANCE_DEG = 5.0
"""An object tilted further than this from upright fails the check (degrees)."""
MASS_KG = {"cylinder": 0.3, "disc": 0.2, "grill": 4.0, "box": 0.5}
"""Mass per shape: a full drinks can or bottle, a plate, a small table grill, a packet. Resting
stability depends on shape and centre of mass, not on mass, so one figure per shape does."""
MESH_DENSITY_KG_M3 = 500.0
"""A mesh object's density (half water's: a toy or a packet, partly hollow), over the volume
of its convex pieces' hulls: its mass follows its size, its centre of mass its shape."""


def object_mass(obj: ObjectSpec) -> float:
    """``obj``'s mass (kg): :data:`MASS_KG` by shape, a mesh's from :data:`MESH_DENSITY_KG_M3`."""
    if obj.shape == "mesh":
        volume, _ = pieces_volume_centroid(object_pieces(obj))
        return MESH_DENSITY_KG_M3 * volume
    return MASS_KG[obj.shape]


@dataclass(frozen=True)
class ObjectDrift:
    """How far one object is from where the plan says it rests."""

    obj: str
    displacement_m: float
    tilt_deg: float


@dataclass(frozen=True)
class StepCheck:
    """One settled step: step 0 is the initial state, step i the state after action i."""

    step: int
    label: str
    largest_move: ObjectDrift | None
    """The object whose frame moved furthest (None: nothing rests, all is held)."""
    largest_tilt: ObjectDrift | None
    beyond: ObjectDrift | None
    """The object furthest beyond the tolerance (relative to it), None if all are within."""


@dataclass(frozen=True)
class PhysicsReport:
    steps: tuple[StepCheck, ...]
    tolerance_m: float
    tolerance_deg: float
    settle_seconds: float

    @property
    def passed(self) -> bool:
        return self.failure is None

    @property
    def failure(self) -> StepCheck | None:
        """The first step with an object beyond the tolerance."""
        return next((step for step in self.steps if step.beyond is not None), None)

    def to_json(self) -> dict[str, object]:
        """What a result record keeps of the check: the verdict, its terms, each step."""

        def drift(d: ObjectDrift | None) -> dict[str, object] | None:
            return None if d is None else {"obj": d.obj, "m": d.displacement_m, "deg": d.tilt_deg}

        return {
            "passed": self.passed,
            "failure": self.failure_line(),
            "tolerance_m": self.tolerance_m,
            "tolerance_deg": self.tolerance_deg,
            "settle_seconds": self.settle_seconds,
            "steps": [
                {
                    "step": step.step,
                    "label": step.label,
                    "largest_move": drift(step.largest_move),
                    "largest_tilt": drift(step.largest_tilt),
                }
                for step in self.steps
            ],
        }

    def failure_line(self) -> str | None:
        """One line naming the failing step and object, or None if the check passed."""
        step = self.failure
        if step is None or step.beyond is None:
            return None
        drift = step.beyond
        return (
            f"physics check fails at step {step.step} ({step.label}): {drift.obj} moved "
            f"{drift.displacement_m * 100:.1f} cm and tilted {drift.tilt_deg:.1f} deg after "
            f"{self.settle_seconds:g} s of settling (tolerance {self.tolerance_m * 100:g} cm, "
            f"{self.tolerance_deg:g} deg)"
        )


def check_physics(
    problem: Problem,
    states: Sequence[State],
    labels: Sequence[str] = (),
    *,
    settle_seconds: float = SETTLE_SECONDS,
    tolerance_m: float = TOLERANCE_M,
    tolerance_deg: float = TOLERANCE_DEG,
) -> PhysicsReport:
    """Settle ``states`` (the initial state, then the state after each action, as a replay
    gives them) under gravity one after the other and measure each; ``labels`` name the
    actions (``labels[i]`` made ``states[i + 1]``). The tolerances must be positive and the
    settling time at least one time step (a StalmError names the one that is not)."""
    _check_terms("check_physics", settle_seconds, tolerance_m, tolerance_deg)
    world = PhysicsWorld(problem)
    try:
        steps = []
        previous: State | None = None
        for index, state in enumerate(states):
            world.show(previous, state)
            world.settle(round(settle_seconds / TIME_STEP))
            drifts = [world.drift(name, pose) for name, pose in state.poses]
            label = "the initial state" if index == 0 else _label(labels, index - 1)
            steps.append(_step_check(index, label, drifts, tolerance_m, tolerance_deg))
            previous = state
        return PhysicsReport(tuple(steps), tolerance_m, tolerance_deg, settle_seconds)
    finally:
        world.close()


def unsettled_objects(
    problem: Problem,
    state: State | None = None,
    *,
    settle_seconds: float = SETTLE_SECONDS,
    tolerance_m: float = TOLERANCE_M,
    tolerance_deg: float = TOLERANCE_DEG,
) -> tuple[ObjectDrift, ...]:
    """Every object that does not rest where ``state`` (the problem's initial state by
    default) puts it: each that moved or tilted beyond the tolerance after settling under
    gravity, the furthest beyond first. A problem file can place a cylinder half over a
    region's edge or a grill on its handles; the planner, being kinematic, would never notice,
    and :func:`check_physics` would then fail every plan at its initial state."""
    _check_terms("unsettled_objects", settle_seconds, tolerance_m, tolerance_deg)
    state = problem.initial_state if state is None else state
    world = PhysicsWorld(problem)
    try:
        world.show(None, state)
        world.settle(round(settle_seconds / TIME_STEP))
        drifts = [world.drift(name, pose) for name, pose in state.poses]
    finally:
        world.close()
    beyond = [d for d in drifts if _excess(d, tolerance_m, tolerance_deg) > 1.0]
    return tuple(sorted(beyond, key=lambda d: -_excess(d, tolerance_m, tolerance_deg)))


def _check_terms(
    caller: str, settle_seconds: float, tolerance_m: float, tolerance_deg: float
) -> None:
    """A StalmError naming the first term of a check that is no positive number (or a
    settling time shorter than one step)."""
    for name, value in (("tolerance_m", tolerance_m), ("tolerance_deg", tolerance_deg)):
        if not (math.isfinite(value) and value > 0):
            raise StalmError(f"{caller}: {name} must be a positive number, got {value!r}")
    if not (math.isfinite(settle_seconds) and settle_seconds >= TIME_STEP):
        raise StalmError(
            f"{caller}: settle_seconds must be at least one time step ({TIME_STEP:.6g} s), "
            f"got {settle_seconds!r}"
        )


def _excess(drift: ObjectDrift, tolerance_m: float, tolerance_deg: float) -> float:
    """How far ``drift`` is past the tolerance, as a multiple of it (above 1: beyond)."""
    return max(drift.displacement_m / tolerance_m, drift.tilt_deg / tolerance_deg)


def _label(labels: Sequence[str], index: int) -> str:
    return labels[index] if index < len(labels) else f"action {index + 1}"


def _step_check(
    index: int, label: str, drifts: list[ObjectDrift], tolerance_m: float, tolerance_deg: float
) -> StepCheck:
    def excess(drift: ObjectDrift) -> float:
        return _excess(drift, tolerance_m, tolerance_deg)

    moved = max(drifts, key=lambda d: d.displacement_m, default=None)
    tilted = max(drifts, key=lambda d: d.tilt_deg, default=None)
    worst = max(drifts, key=excess, default=None)
    beyond = worst if worst is not None and excess(worst) > 1.0 else None
    return StepCheck(index, label, moved, tilted, beyond)


def centre_of_mass(obj: ObjectSpec) -> tuple[float, float, float]:
    """The centroid of ``obj``'s shape in its frame (origin at the bottom face's centre),
    for a uniform density (a grill's handles pull it a little toward their height, a mesh's is
    its convex pieces' centroid)."""
    if obj.shape == "mesh":
        return pieces_volume_centroid(object_pieces(obj))[1]
    if obj.shape != "grill":
        return (0.0, 0.0, obj.half_extents[2])
    assert obj.size is not None
    sx, sy, sz = obj.size
    body = sx * sy * sz
    handle = (2 * GRILL_HANDLE_HALF_HEIGHT) ** 2 * GRILL_HANDLE_REACH
    return (0.0, 0.0, (body * sz / 2 + 2 * handle * obj.handle_z) / (body + 2 * handle))


class PhysicsWorld:
    """One problem's bodies in a DIRECT client with gravity, objects dynamic."""

    def __init__(self, problem: Problem) -> None:
        spec = problem.spec
        self.client = c = p.connect(p.DIRECT)
        try:
            robot = robot_named(spec.robot.robot)
            bodies = build_bodies(c, spec, robot)
            for fixed in (bodies.base, *bodies.doors.values()):
                p.changeDynamics(fixed, -1, mass=0.0, physicsClientId=c)
            self.objects: dict[str, int] = {}
            self.offsets: dict[str, tuple[float, float, float]] = {}
            for obj in spec.objects:
                p.removeBody(bodies.objects[obj.name], physicsClientId=c)
                col, vis = object_shapes(c, obj)
                self.offsets[obj.name] = centre_of_mass(obj)
                self.objects[obj.name] = p.createMultiBody(
                    object_mass(obj),
                    col,
                    vis,
                    [0.0, 0.0, -10.0],
                    baseInertialFramePosition=list(self.offsets[obj.name]),
                    physicsClientId=c,
                )
            p.setGravity(0.0, 0.0, GRAVITY, physicsClientId=c)
            p.setTimeStep(TIME_STEP, physicsClientId=c)
        except BaseException:
            p.disconnect(c)
            raise
        self.spec = spec
        self.bodies = bodies
        self.mount_forward = robot.platform.arm_mount_forward
        self.arm_links = range(-1, p.getNumJoints(bodies.arm, physicsClientId=c))
        self.pin: int | None = None
        self.pinned: str | None = None

    def show(self, previous: State | None, state: State) -> None:
        """Set the robot and doors as ``state`` has them; at the start put every object at
        its pose, after a PLACE put the released object at its planned pose, and pin what
        the hand holds at the hand."""
        c = self.client
        base = state.robot.base
        p.resetBasePositionAndOrientation(
            self.bodies.base, [base[0], base[1], 0.0], yaw_quat(base[2]), physicsClientId=c
        )
        mount = robot_model.arm_mount(base, state.robot.lift, self.mount_forward)
        p.resetBasePositionAndOrientation(
            self.bodies.arm, [mount.x, mount.y, mount.z], yaw_quat(mount.yaw), physicsClientId=c
        )
        joints = self.bodies.joints
        for joint, value in zip(joints.arm, state.robot.arm, strict=True):
            p.resetJointState(self.bodies.arm, joint, value, physicsClientId=c)
        for joint, value in joints.fingers:
            p.resetJointState(self.bodies.arm, joint, value, physicsClientId=c)
        for door in self.spec.doors:
            yaw = door.open_yaw if state.is_open(door.name) else door.closed_yaw
            p.resetBasePositionAndOrientation(
                self.bodies.doors[door.name],
                [door.hinge[0], door.hinge[1], 0.0],
                yaw_quat(yaw),
                physicsClientId=c,
            )
        self._unpin()
        for name, pose in state.poses:
            if previous is None or not previous.has_pose(name):
                self.put(name, (pose.x, pose.y, pose.z), yaw_quat(pose.yaw))
        if state.held is not None:
            self._pin(state)

    def _pin(self, state: State) -> None:
        assert state.held is not None
        c, name = self.client, state.held.obj
        hand = self.bodies.joints.grasp_pose(c, self.bodies.arm)
        position, orientation = p.multiplyTransforms(
            *hand, state.held.position, state.held.orientation, physicsClientId=c
        )
        com = self.put(name, position, orientation)
        for link in self.arm_links:
            p.setCollisionFilterPair(
                self.bodies.arm, self.objects[name], link, -1, 0, physicsClientId=c
            )
        self.pin = p.createConstraint(
            self.objects[name],
            -1,
            -1,
            -1,
            p.JOINT_FIXED,
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            com,
            childFrameOrientation=orientation,
            physicsClientId=c,
        )
        self.pinned = name

    def _unpin(self) -> None:
        if self.pin is None or self.pinned is None:
            return
        p.removeConstraint(self.pin, physicsClientId=self.client)
        for link in self.arm_links:
            p.setCollisionFilterPair(
                self.bodies.arm, self.objects[self.pinned], link, -1, 1, physicsClientId=self.client
            )
        self.pin = self.pinned = None

    def put(
        self, name: str, position: Sequence[float], orientation: Sequence[float]
    ) -> list[float]:
        """Put ``name``'s frame at a pose, at rest; returns its centre of mass there."""
        c, body = self.client, self.objects[name]
        com, _ = p.multiplyTransforms(
            position, orientation, self.offsets[name], (0.0, 0.0, 0.0, 1.0), physicsClientId=c
        )
        p.resetBasePositionAndOrientation(body, com, orientation, physicsClientId=c)
        p.resetBaseVelocity(body, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=c)
        return list(com)

    def settle(self, steps: int) -> None:
        for _ in range(steps):
            p.stepSimulation(physicsClientId=self.client)

    def drift(self, name: str, planned: ObjectPose) -> ObjectDrift:
        """How far ``name``'s frame is from ``planned``, and its tilt from upright."""
        c = self.client
        com, orientation = p.getBasePositionAndOrientation(self.objects[name], physicsClientId=c)
        back = [-value for value in self.offsets[name]]
        frame, _ = p.multiplyTransforms(
            com, orientation, back, (0.0, 0.0, 0.0, 1.0), physicsClientId=c
        )
        axis_z = p.getMatrixFromQuaternion(orientation, physicsClientId=c)[8]
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, axis_z))))
        gap = math.dist(frame, (planned.x, planned.y, planned.z))
        return ObjectDrift(name, gap, tilt)

    def close(self) -> None:
        if p.isConnected(self.client):
            p.disconnect(self.client)
