"""The samplers ψ of §4.1: continuous parameters for PICK, PLACE and OPEN.

Each sampler draws from the passed generator, checks what it drew with real collision
queries, and retries up to the operator's number of tries. It returns either a feasible κ or
an :class:`~stalm.domain.outcome.Infeasibility` saying why every try failed. The base path
does not depend on the draw, so it is planned once per call.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.outcome import Infeasibility
from stalm.domain.params import OpenParams, PickParams, PlaceParams
from stalm.errors import StalmError
from stalm.geometry.transforms import Pose3, compose, invert, wrap_angle
from stalm.motion.arm_motion import interpolate_waypoints
from stalm.motion.base_motion import BasePath, BasePlanner
from stalm.motion.colliders import ENGINES, Engine
from stalm.motion.grasps import (
    PITCH_RANGE,
    YAW_RANGE,
    draw_placement,
    grasp_window,
    gripper_target,
    sample_grasp_angles,
)
from stalm.motion.manipulation import ArmMotion, Manipulator, handle_target, placing_hand
from stalm.world.grip_widths import too_wide
from stalm.world.relations import direction_between, supporting_region
from stalm.world.scene import Sim
from stalm.world.spec import RegionSpec
from stalm.world.state import Grasp, ObjectPose, RobotConf, State


@dataclass(frozen=True)
class SamplerSettings:
    """Numbers of §4.1 and of the authors' code."""

    pick_tries: int = 30
    place_tries: int = 40
    open_tries: int = 1
    placement_draws: int = 41
    pitch_range: tuple[float, float] = PITCH_RANGE
    yaw_range: tuple[float, float] = YAW_RANGE
    ik_attempts: int = 4
    engine: Engine = "batched"
    """How ψ's motions are checked: 'batched' (compiled candidate tests, each candidate
    confirmed by PyBullet) or 'pybullet' (every configuration queried; the reference). Both
    find the same contacts (:mod:`stalm.motion.colliders`)."""

    def __post_init__(self) -> None:
        if self.engine not in ENGINES:
            raise StalmError(
                f"setting samplers.engine must be one of {', '.join(ENGINES)}, got {self.engine!r}"
            )


class Failures:
    """Tally of why tries failed; the most frequent kind is reported."""

    def __init__(self) -> None:
        self.kinds: Counter[str] = Counter()
        self.details: dict[str, str] = {}
        self.blockers: dict[str, set[str]] = {}

    def add(self, kind: str, detail: str, blockers: set[str] | None = None) -> None:
        self.kinds[kind] += 1
        self.details.setdefault(kind, detail)
        self.blockers.setdefault(kind, set()).update(blockers or set())

    def result(self, default: str) -> Infeasibility:
        if not self.kinds:
            return Infeasibility("no_ik", default)
        kind = max(self.kinds, key=lambda k: (self.kinds[k], -list(self.kinds).index(k)))
        return Infeasibility(kind, self.details[kind], tuple(sorted(self.blockers[kind])))


class Samplers:
    """ψ for one problem's scene. Uses (and leaves changed) the sim's configuration."""

    def __init__(self, sim: Sim, base_planner: BasePlanner, settings: SamplerSettings) -> None:
        self.sim = sim
        self.problem = sim.problem
        self.base = base_planner
        self.settings = settings
        self.hands = Manipulator(sim, settings.engine)

    # ------------------------------------------------------------------ shared
    def names(self, bodies: set[int]) -> set[str]:
        return {self.sim.bodies.name_of(b) for b in bodies}

    def base_path(self, state: State, goal: tuple[float, float, float]) -> BasePath | Infeasibility:
        """Route from the robot's pose to ``goal`` with what it holds, or why not."""
        self.sim.set_state(state)
        result = self.base.plan(state.robot.base, goal, state.open_doors)
        if result.path is not None:
            return result.path
        blockers = self.names(set(result.blockers))
        closed = frozenset(d.name for d in self.problem.doors) - state.open_doors
        if closed:
            every_door_open = frozenset(d.name for d in self.problem.doors)
            if self.base.route(state.robot.base, goal, every_door_open) is not None:
                blockers |= set(closed)
        return Infeasibility(
            "base_path_blocked",
            f"no base path from {_fmt(state.robot.base)} to {_fmt(goal)}",
            tuple(sorted(blockers)),
        )

    def arm_motion_free(
        self,
        base: tuple[float, float, float],
        waypoints: tuple[tuple[float, ...], ...],
        ignore: set[int],
    ) -> set[int]:
        return self.hands.collider.arm_first_touch(base, interpolate_waypoints(waypoints), ignore)

    # ------------------------------------------------------------------ PICK
    def pick(
        self, state: State, action: Pick, rng: np.random.Generator
    ) -> PickParams | Infeasibility:
        obj = self.problem.object(action.obj)
        pose = state.pose(action.obj)
        region_name = supporting_region(self.problem, pose)
        if region_name is None:
            return Infeasibility("precondition", f"'{action.obj}' rests on no region")
        region = self.problem.region(region_name)
        stand = region.base_pose
        path = self.base_path(state, stand)
        if isinstance(path, Infeasibility):
            return path
        window = grasp_window(
            obj,
            pose,
            stand,
            self.settings.pitch_range,
            self.settings.yaw_range,
            gap=self.sim.robot.gripper.opening,
        )
        if window is None:
            wide = too_wide(obj, self.sim.robot.gripper.opening)
            return Infeasibility(
                "no_ik",
                f"'{action.obj}': {wide}"
                if wide is not None
                else f"no grasp of '{action.obj}' fits from {region_name}'s standing pose",
            )
        failures = Failures()
        for _ in range(self.settings.pick_tries):
            pitch, yaw = sample_grasp_angles(rng, window.pitch_range, window.yaw_range)
            target = gripper_target(window.point, stand[2], pitch, yaw)
            self.sim.set_state(state)
            self.sim.set_base_only(stand)
            reached = False
            for motion in self.hands.picks(stand, target, rng, self.settings.ik_attempts):
                reached = True
                picked = self._pick_motion(state, action, motion, failures)
                if picked is not None:
                    return PickParams(
                        base_path=path,
                        pitch=pitch,
                        yaw=yaw,
                        grasp=picked,
                        grasp_conf=motion.key_conf,
                        arm_waypoints=motion.waypoints,
                    )
            if not reached:
                failures.add("no_ik", f"no IK solution to grasp '{action.obj}'")
        return failures.result(f"no grasp of '{action.obj}' found")

    def _pick_motion(
        self, state: State, action: Pick, motion: ArmMotion, failures: Failures
    ) -> Grasp | None:
        """The grasp a collision-free pick ``motion`` takes (None, with the failure noted, if
        it collides), checked in the world of ``state`` with the base at the standing pose."""
        stand = motion.stand
        self.sim.set_state(state)  # a motion checked before may have moved the object
        self.sim.set_base_only(stand)
        hits = self.arm_motion_free(stand, motion.into, {self.sim.bodies.objects[action.obj]})
        if hits:
            failures.add("arm_collision", f"reaching for '{action.obj}' collides", self.names(hits))
            return None
        self.sim.set_arm(stand, motion.key_conf[0], motion.key_conf[1:])
        grasp_pose = compose(invert(self.sim.gripper_pose()), self.sim.object_pose(action.obj))
        grasp = Grasp.make(action.obj, grasp_pose[0], grasp_pose[1])
        self.sim.attach(grasp)
        hits = self.arm_motion_free(stand, motion.out, set())
        self.sim.attach(None)
        if hits:
            failures.add("arm_collision", f"lifting '{action.obj}' collides", self.names(hits))
            return None
        return grasp

    # ------------------------------------------------------------------ PLACE
    def target_region(self, state: State, action: Place) -> RegionSpec | Infeasibility:
        if action.direction == "on":
            return self.problem.region(action.ref)
        if not state.has_pose(action.ref):
            return Infeasibility(
                "precondition", f"reference '{action.ref}' is not resting anywhere"
            )
        name = supporting_region(self.problem, state.pose(action.ref))
        if name is None:
            return Infeasibility("precondition", f"reference '{action.ref}' rests on no region")
        return self.problem.region(name)

    def draw_placement(
        self, state: State, action: Place, region: RegionSpec, yaw: float, rng: np.random.Generator
    ) -> ObjectPose | None:
        """Uniform (x, y) on the region's usable area, rejected until it lies in ``dir``."""
        obj = self.problem.object(action.obj)
        ref_pose = state.pose(action.ref) if action.direction != "on" else None
        for _ in range(self.settings.placement_draws):
            pose = draw_placement(obj, region, yaw, rng)
            if pose is None:
                return None
            if ref_pose is None or direction_between(region, pose, ref_pose) == action.direction:
                return pose
        return None

    def place(
        self, state: State, action: Place, rng: np.random.Generator
    ) -> PlaceParams | Infeasibility:
        assert state.held is not None
        region = self.target_region(state, action)
        if isinstance(region, Infeasibility):
            return region
        stand = region.base_pose
        path = self.base_path(state, stand)
        if isinstance(path, Infeasibility):
            return path
        body = self.sim.bodies.objects[action.obj]
        yaw = wrap_angle(stand[2] + state.held_yaw_offset)
        failures = Failures()
        robot_bodies = {self.sim.bodies.base, self.sim.bodies.arm}
        for _ in range(self.settings.place_tries):
            self.sim.set_state(state)
            self.sim.set_base_only(stand)
            placement = self.draw_placement(state, action, region, yaw, rng)
            if placement is None:
                failures.add(
                    "no_placement",
                    f"no placement {action.direction} '{action.ref}' drawn on '{region.name}'",
                )
                continue
            self.sim.attach(None)
            self.sim.place_object(action.obj, placement)
            hits = self.sim.contacts_of([body], robot_bodies)
            if hits:
                failures.add(
                    "no_placement",
                    f"placements of '{action.obj}' on '{region.name}' collide",
                    self.names(hits),
                )
                continue
            hand = placing_hand(placement, state.held)
            reached = False
            for motion in self.hands.places(stand, hand, rng, self.settings.ik_attempts):
                reached = True
                if self._place_motion_free(state, action, placement, motion, failures):
                    return PlaceParams(
                        base_path=path,
                        placement=placement,
                        place_conf=motion.key_conf,
                        arm_waypoints=motion.waypoints,
                    )
            if not reached:
                failures.add("no_ik", f"no IK solution to place '{action.obj}' on '{region.name}'")
        return failures.result(f"no placement of '{action.obj}' found")

    def _place_motion_free(
        self,
        state: State,
        action: Place,
        placement: ObjectPose,
        motion: ArmMotion,
        failures: Failures,
    ) -> bool:
        """Is the placement ``motion`` collision-free (the failure noted if not)? Checked in
        the world of ``state`` with the base at the standing pose."""
        assert state.held is not None
        stand = motion.stand
        self.sim.set_state(state)  # a motion checked before may have moved the object
        self.sim.set_base_only(stand)
        self.sim.attach(state.held, state.held_yaw_offset)
        hits = self.arm_motion_free(stand, motion.into, set())
        if hits:
            failures.add("arm_collision", f"placing '{action.obj}' collides", self.names(hits))
            return False
        self.sim.attach(None)
        self.sim.place_object(action.obj, placement)
        body = self.sim.bodies.objects[action.obj]
        hits = self.arm_motion_free(stand, motion.out, {body})
        if hits:
            failures.add(
                "arm_collision", f"retreating from '{action.obj}' collides", self.names(hits)
            )
            return False
        return True

    # ------------------------------------------------------------------ OPEN
    def handle_target(self, door_name: str, stand: tuple[float, float, float]) -> Pose3:
        """The door's fixed handle grasp on the robot's side: horizontal, facing the panel."""
        return handle_target(self.problem.door(door_name), stand)

    def open(
        self, state: State, action: Open, rng: np.random.Generator
    ) -> OpenParams | Infeasibility:
        door = self.problem.door(action.door)
        door_body = self.sim.bodies.doors[action.door]
        failures = Failures()
        stands = sorted(door.base_poses, key=lambda s: math.dist(s[:2], state.robot.base[:2]))
        for stand in stands:
            path = self.base_path(state, stand)
            if isinstance(path, Infeasibility):
                failures.add(path.kind, path.detail, set(path.blockers))
                continue
            for _ in range(self.settings.open_tries):
                self.sim.set_state(state)
                self.sim.set_base_only(stand)
                motion = self.hands.open(action.door, stand, rng, self.settings.ik_attempts)
                if motion is None:
                    failures.add("no_ik", f"no IK solution to the handle of '{action.door}'")
                    continue
                hits = self.arm_motion_free(stand, motion.waypoints, {door_body})
                if hits:
                    failures.add(
                        "arm_collision",
                        f"reaching the handle of '{action.door}' collides",
                        self.names(hits),
                    )
                    continue
                carry = self.sim.robot.carry_conf
                self.sim.set_robot(RobotConf.make(stand, carry[0], carry[1:]))
                self.sim.set_door(action.door, True)
                hits = {b for b in self.sim.contacts_of([door_body]) if not self.sim.is_static(b)}
                self.sim.set_door(action.door, False)
                if hits:
                    failures.add(
                        "door_blocked", f"'{action.door}' cannot swing open", self.names(hits)
                    )
                    continue
                return OpenParams(
                    base_path=path,
                    handle_conf=motion.key_conf,
                    arm_waypoints=motion.waypoints,
                )
        return failures.result(f"'{action.door}' could not be opened")


def _fmt(pose: tuple[float, float, float]) -> str:
    return f"({pose[0]:.2f}, {pose[1]:.2f}, {pose[2]:.2f})"
