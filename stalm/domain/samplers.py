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
from stalm.geometry.transforms import (
    Pose3,
    compose,
    gripper_rotation,
    invert,
    matrix_from_quat,
    quat_from_matrix,
    se2_to_local,
    se2_to_world,
    wrap_angle,
    yaw_quat,
)
from stalm.motion.arm_motion import first_collision, interpolate_waypoints
from stalm.motion.base_motion import BasePath, BasePlanner
from stalm.motion.ik import IKSolution, solve_ik, solve_ik_from
from stalm.world import robot as robot_model
from stalm.world.relations import direction_between, supporting_region
from stalm.world.scene import Sim
from stalm.world.spec import GRILL_HANDLE_REACH, ObjectSpec, RegionSpec
from stalm.world.state import Grasp, ObjectPose, RobotConf, State

CARRY_CONF = (robot_model.CARRY_LIFT, *robot_model.CARRY_ARM)
APPROACH_DISTANCE = 0.08
"""The gripper comes in (and backs out) along its approach axis over this distance (m)."""
LIFT_DISTANCE = 0.05
"""A grasped object is raised this much before the arm folds back (m)."""
PLACE_CLEARANCE = 0.12
"""A held object is lowered onto its placement from this height above it (m)."""


@dataclass(frozen=True)
class SamplerSettings:
    """Numbers of §4.1 and the authors' code (research notes)."""

    pick_tries: int = 30
    place_tries: int = 40
    open_tries: int = 1
    placement_draws: int = 41
    pitch_range: tuple[float, float] = (0.0, math.radians(45.0))
    yaw_range: tuple[float, float] = (math.radians(-60.0), math.radians(60.0))
    ik_attempts: int = 4


def grasp_points(obj: ObjectSpec) -> list[tuple[float, float, float]]:
    """Candidate grasp points in the object's frame (origin at its bottom centre)."""
    if obj.shape == "grill":
        assert obj.size is not None
        _sx, sy, sz = obj.size
        side = sy / 2 + GRILL_HANDLE_REACH * 0.6
        return [(0.0, side, sz * 0.75), (0.0, -side, sz * 0.75)]
    assert obj.radius is not None and obj.height is not None
    if obj.shape == "disc":
        # a plate is taken at its rim from above: the grasp point sits just over the rim
        r, z = obj.radius * 0.85, obj.height + 0.012
        return [(r, 0.0, z), (-r, 0.0, z), (0.0, r, z), (0.0, -r, z)]
    return [(0.0, 0.0, min(obj.height / 2, 0.09))]


def nearest_grasp_point(
    obj: ObjectSpec, pose: ObjectPose, base: tuple[float, float, float]
) -> tuple[float, float, float]:
    """The object's grasp point nearest the standing pose, in world coordinates."""
    best: tuple[float, float, float] | None = None
    best_distance = math.inf
    for gx, gy, gz in grasp_points(obj):
        wx, wy = se2_to_world((pose.x, pose.y, pose.yaw), gx, gy)
        distance = math.hypot(wx - base[0], wy - base[1])
        if distance < best_distance - 1e-9:
            best, best_distance = (wx, wy, pose.z + gz), distance
    assert best is not None
    return best


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
        self, base: tuple[float, float, float], waypoints: list[tuple[float, ...]], ignore: set[int]
    ) -> set[int]:
        return first_collision(self.sim, base, interpolate_waypoints(waypoints), ignore)

    def offset_conf(
        self,
        base: tuple[float, float, float],
        target: Pose3,
        solution: IKSolution,
        backoff: float = 0.0,
        raise_by: float = 0.0,
    ) -> tuple[float, ...]:
        """The configuration with the gripper backed off along its approach axis or raised;
        falls back to the target configuration itself when IK cannot reach the offset pose."""
        rot = gripper_axis(target)
        x, y, z = target[0]
        moved: Pose3 = (
            (x - backoff * rot[0], y - backoff * rot[1], z - backoff * rot[2] + raise_by),
            target[1],
        )
        near = solve_ik_from(self.sim, base, moved, solution)
        return _conf(near if near is not None else solution)

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
        point = nearest_grasp_point(obj, pose, stand)
        body = self.sim.bodies.objects[action.obj]
        failures = Failures()
        for _ in range(self.settings.pick_tries):
            pitch = float(rng.uniform(*self.settings.pitch_range))
            yaw = float(rng.uniform(*self.settings.yaw_range))
            target: Pose3 = (point, quat_from_matrix(gripper_rotation(stand[2] + yaw, pitch)))
            self.sim.set_state(state)
            self.sim.set_base_only(stand)
            solution = solve_ik(self.sim, stand, target, rng, self.settings.ik_attempts)
            if solution is None:
                failures.add("no_ik", f"no IK solution to grasp '{action.obj}'")
                continue
            grasp_conf = _conf(solution)
            pre_conf = self.offset_conf(stand, target, solution, backoff=APPROACH_DISTANCE)
            approach = [CARRY_CONF, pre_conf, grasp_conf]
            hits = self.arm_motion_free(stand, approach, {body})
            if hits:
                failures.add(
                    "arm_collision", f"reaching for '{action.obj}' collides", self.names(hits)
                )
                continue
            self.sim.set_arm(stand, solution.lift, solution.arm)
            grasp_pose = compose(invert(self.sim.gripper_pose()), self.sim.object_pose(action.obj))
            grasp = Grasp.make(action.obj, grasp_pose[0], grasp_pose[1])
            up_conf = self.offset_conf(stand, target, solution, raise_by=LIFT_DISTANCE)
            self.sim.attach(grasp)
            hits = self.arm_motion_free(stand, [grasp_conf, up_conf, CARRY_CONF], set())
            self.sim.attach(None)
            if hits:
                failures.add("arm_collision", f"lifting '{action.obj}' collides", self.names(hits))
                continue
            return PickParams(
                base_path=path,
                pitch=pitch,
                yaw=yaw,
                grasp=grasp,
                grasp_conf=grasp_conf,
                arm_waypoints=(*approach, up_conf, CARRY_CONF),
            )
        return failures.result(f"no grasp of '{action.obj}' found")

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
        hx, hy, _ = obj.half_extents
        rel = wrap_angle(yaw - region.yaw)
        ex = abs(math.cos(rel)) * hx + abs(math.sin(rel)) * hy
        ey = abs(math.sin(rel)) * hx + abs(math.cos(rel)) * hy
        ux, uy = region.usable_size
        half_u, half_v = ux / 2 - ex, uy / 2 - ey
        if half_u < 0 or half_v < 0:
            return None
        ref_pose = state.pose(action.ref) if action.direction != "on" else None
        for _ in range(self.settings.placement_draws):
            u = float(rng.uniform(-half_u, half_u))
            v = float(rng.uniform(-half_v, half_v))
            x, y = se2_to_world((*region.center, region.yaw), u, v)
            pose = ObjectPose.make(x, y, region.top, yaw)
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
            object_pose: Pose3 = ((placement.x, placement.y, placement.z), yaw_quat(placement.yaw))
            hand = compose(object_pose, invert(state.held.pose))
            solution = solve_ik(self.sim, stand, hand, rng, self.settings.ik_attempts)
            if solution is None:
                failures.add("no_ik", f"no IK solution to place '{action.obj}' on '{region.name}'")
                continue
            place_conf = _conf(solution)
            above_conf = self.offset_conf(stand, hand, solution, raise_by=PLACE_CLEARANCE)
            self.sim.attach(state.held, state.held_yaw_offset)
            hits = self.arm_motion_free(stand, [CARRY_CONF, above_conf, place_conf], set())
            if hits:
                failures.add("arm_collision", f"placing '{action.obj}' collides", self.names(hits))
                continue
            self.sim.attach(None)
            self.sim.place_object(action.obj, placement)
            back_conf = self.offset_conf(stand, hand, solution, backoff=APPROACH_DISTANCE)
            hits = self.arm_motion_free(stand, [place_conf, back_conf, CARRY_CONF], {body})
            if hits:
                failures.add(
                    "arm_collision", f"retreating from '{action.obj}' collides", self.names(hits)
                )
                continue
            return PlaceParams(
                base_path=path,
                placement=placement,
                place_conf=place_conf,
                arm_waypoints=(CARRY_CONF, above_conf, place_conf, back_conf, CARRY_CONF),
            )
        return failures.result(f"no placement of '{action.obj}' found")

    # ------------------------------------------------------------------ OPEN
    def handle_target(self, door_name: str, stand: tuple[float, float, float]) -> Pose3:
        """The door's fixed handle grasp on the robot's side: horizontal, facing the panel."""
        door = self.problem.door(door_name)
        su, sv = se2_to_local((*door.hinge, door.closed_yaw), stand[0], stand[1])
        side = 1.0 if sv > 0 else -1.0
        reach = door.thickness / 2 + 0.05 - 0.015
        x, y = se2_to_world((*door.hinge, door.closed_yaw), door.handle_distance, side * reach)
        approach = wrap_angle(door.closed_yaw - side * math.pi / 2)
        del su
        return (x, y, door.handle_height), quat_from_matrix(gripper_rotation(approach, 0.0))

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
                solution = solve_ik(
                    self.sim,
                    stand,
                    self.handle_target(action.door, stand),
                    rng,
                    self.settings.ik_attempts * 3,
                )
                if solution is None:
                    failures.add("no_ik", f"no IK solution to the handle of '{action.door}'")
                    continue
                handle_conf = (solution.lift, *solution.arm)
                hits = self.arm_motion_free(
                    stand, [CARRY_CONF, handle_conf, CARRY_CONF], {door_body}
                )
                if hits:
                    failures.add(
                        "arm_collision",
                        f"reaching the handle of '{action.door}' collides",
                        self.names(hits),
                    )
                    continue
                self.sim.set_robot(RobotConf.make(stand, CARRY_CONF[0], CARRY_CONF[1:]))
                self.sim.set_door(action.door, True)
                hits = self.sim.contacts_of([door_body])
                self.sim.set_door(action.door, False)
                if hits:
                    failures.add(
                        "door_blocked", f"'{action.door}' cannot swing open", self.names(hits)
                    )
                    continue
                return OpenParams(
                    base_path=path,
                    handle_conf=handle_conf,
                    arm_waypoints=(CARRY_CONF, handle_conf, CARRY_CONF),
                )
        return failures.result(f"'{action.door}' could not be opened")


def _conf(solution: IKSolution) -> tuple[float, ...]:
    return (solution.lift, *solution.arm)


def gripper_axis(target: Pose3) -> tuple[float, float, float]:
    """The approach direction (+z of the gripper frame) of a gripper pose."""
    rot = matrix_from_quat(target[1])
    return (float(rot[0, 2]), float(rot[1, 2]), float(rot[2, 2]))


def _fmt(pose: tuple[float, float, float]) -> str:
    return f"({pose[0]:.2f}, {pose[1]:.2f}, {pose[2]:.2f})"
