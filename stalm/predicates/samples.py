"""The sampled motions behind the occlusion literals, drawn as the operators draw them.

An occlusion literal (paper §3.2) says which movables the motion of an action touches when
the motion is planned ignoring them. This module samples those motions: the base route to each
region, a fixed number of picks per resting object, placements per object and region, and
placements targeted at one relative position. The motions themselves are built by
:class:`~stalm.motion.manipulation.Manipulator`, as PICK's and PLACE's samplers build them.

Each action's draws come from a generator seeded by the action's own key
(:func:`stable_seed`: its names, not its continuous values), so what is sampled for one action
does not depend on what else was computed before, nor on the last bits of the grasp it is
drawn for. The literals, and which samples are drawn again when the state changes, are
:class:`~stalm.predicates.engine.PredicateEngine`'s.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from stalm.cores import check_process_count
from stalm.errors import StalmError
from stalm.geometry.transforms import Pose3, compose, invert, quat_yaw, wrap_angle, yaw_quat
from stalm.motion.base_motion import BasePlanner
from stalm.motion.colliders import ENGINES, Engine
from stalm.motion.grasps import (
    PITCH_RANGE,
    YAW_RANGE,
    draw_placement,
    grasp_window,
    gripper_target,
    sample_grasp_angles,
)
from stalm.motion.manipulation import Manipulator, placing_hand, route_segment
from stalm.motion.sweeps import Segment, SweptMotion, sweep
from stalm.world.relations import direction_between, supporting_region
from stalm.world.scene import PENETRATION_TOLERANCE, Sim
from stalm.world.spec import ProblemSpec, RegionSpec, footprints_overlap
from stalm.world.state import Grasp, ObjectPose


@dataclass(frozen=True)
class PredicateSettings:
    """Sample counts per action; the authors checked 12 samples per predicate.

    An action none of whose samples is statically feasible is reported as one that cannot be
    done (``CannotPick``/``CannotPlace``), so before saying so the engine keeps drawing, up to
    five times the operator's own tries (PICK's 30, PLACE's 40): an action the operator's
    sampler can do in a few of its tries (P4's plate, picked by a few of PICK's 30 draws) is
    then found, and one the engine gives up on is one the operator would almost never do."""

    pick_samples: int = 12
    pick_draws_until_one: int = 150
    """While no pick of an object is feasible, draw up to this many (5 x PICK's 30)."""
    placements_per_region: int = 8
    placement_draws: int = 24
    placement_draws_until_one: int = 200
    """While no placement of the held object on a region is feasible, draw up to this many
    (5 x PLACE's 40)."""
    targeted_draws: int = 41
    targeted_draws_until_one: int = 205
    """While no placement of the held object beside a reference is feasible, draw up to this
    many (5 x the 41 draws PLACE makes per try for a direction)."""
    targeted_samples: int = 1
    ik_attempts: int = 4
    seed: int = 0
    relevant_only: bool = False
    """Beyond the paper (off for its rows): occlusion literals only for the objects a plan
    must touch: the goal's objects, what occludes picking them or placing them at their goal,
    and recursively what occludes picking those (Hcount's set M, Appendix C); placements only
    of the goal's objects at their goal (where an occluder is put down is left to Concretize,
    which checks it). A scene of many objects with a few goal objects then costs about what a
    small one does (``PredicateEngine``)."""
    relevant_above: int | None = 64
    """Beyond the paper: on a problem of more movable objects than this, a run's resolved
    settings (:meth:`~stalm.settings.tree.RunSettings.resolved`: ``stalm solve``, ``stalm
    experiment``, ``stalm rerun``) make the predicates relevant-only whatever
    ``relevant_only`` says (None: never); an engine built directly computes what it is
    asked. The paper's predicates sweep every object's picks and placements, and past about
    a hundred objects they alone outrun a budget while a plan touches a handful (a generated
    120-object problem spent 205 s of its 300 s on them and timed out; relevant-only, it
    solved in 42 s). P1-P6 (at most 24 objects) and the scale suite up to 64 keep the
    paper's (:meth:`for_objects`)."""
    workers: int = 1
    """Processes for a state's full computation (beyond the paper; 1: the trial's own only).
    Forked copies of the process each sample a share of the actions
    (:mod:`stalm.predicates.forked`) and the literals are the same for any number; the
    cheaper cached updates after an action stay in one process. An experiment running
    trials side by side must leave a core per process (``stalm experiment`` checks); more
    than the cores this process may use is refused (:func:`~stalm.cores.check_process_count`)."""
    engine: Engine = "batched"
    """How the sampled motions are swept: 'batched' (compiled candidate tests, each candidate
    confirmed by PyBullet) or 'pybullet' (every configuration queried; the reference). Both
    give the same literals (:mod:`stalm.motion.colliders`)."""

    def __post_init__(self) -> None:
        check_process_count("setting predicates.workers", self.workers)
        above = self.relevant_above
        whole = isinstance(above, int) and not isinstance(above, bool)
        if above is not None and not (whole and above >= 0):
            raise StalmError(
                "setting predicates.relevant_above must be a whole number of objects (0 or "
                f"more) or null (never), got {above!r}"
            )
        if self.engine not in ENGINES:
            raise StalmError(
                f"setting predicates.engine must be one of {', '.join(ENGINES)}, got "
                f"{self.engine!r}"
            )

    def for_objects(self, count: int) -> PredicateSettings:
        """These settings on a problem of ``count`` movable objects: relevant-only above
        ``relevant_above`` (the same settings otherwise, and when they already are)."""
        if self.relevant_only or self.relevant_above is None or count <= self.relevant_above:
            return self
        return replace(self, relevant_only=True)


@dataclass(frozen=True)
class PlacementSample:
    pose: ObjectPose
    motion: SweptMotion


@dataclass(frozen=True)
class PickRecord:
    """The sampled picks of one resting object: the statically feasible motions, and the grasp
    that placements of the object use (the first feasible one; None if it is unreachable)."""

    pose: ObjectPose
    region: str
    grasp: Grasp | None
    yaw_offset: float
    motions: tuple[SweptMotion, ...]


def stable_seed(*parts: int | str) -> int:
    """A seed from an action's key, the same in every process (``hash`` is salted).

    The key holds names and integers only, never a continuous value: a grasp or a pose
    computed by IK differs in its last bits from one CPU to another, and a seed taken from
    its digits would draw other samples there (other literals, another plan)."""
    if not all(isinstance(part, int | str) for part in parts):
        raise TypeError(f"a sample seed's key holds names and integers only: {parts!r}")
    digest = hashlib.sha256(repr(parts).encode()).digest()
    return int.from_bytes(digest[:8], "little")


class MotionSamples:
    """Samples the motions of one problem's actions in its simulator (which it moves).

    The caller sets the world: every sample is swept against the objects standing where the
    simulator has them, and each motion records the movables and doors it touched.
    """

    def __init__(
        self,
        spec: ProblemSpec,
        sim: Sim,
        base_planner: BasePlanner,
        settings: PredicateSettings,
        grasp_ranges: tuple[tuple[float, float], tuple[float, float]] = (PITCH_RANGE, YAW_RANGE),
    ) -> None:
        self.pitch_range, self.yaw_range = grasp_ranges
        """PICK's gripper pitch and yaw ranges (the operator's own: its settings' ranges)."""
        self.spec = spec
        self.sim = sim
        self.base_planner = base_planner
        self.settings = settings
        self.hands = Manipulator(sim, settings.engine)
        self._all_open = frozenset(d.name for d in spec.doors)
        self._names = {b: n for n, b in sim.bodies.objects.items()} | {
            b: n for n, b in sim.bodies.doors.items()
        }

    def _sweep(
        self, segments: tuple[Segment, ...], clear_of: str | None = None
    ) -> SweptMotion | None:
        """Sweep; None if the motion hits the static scene (no moving of objects frees it) or
        the object ``clear_of`` (a placement's own reference)."""
        refuse = frozenset({self.sim.bodies.objects[clear_of]}) if clear_of else frozenset()
        swept = self.hands.sweep(segments, refuse)
        if swept is None:
            return None
        motion, bodies = swept
        return replace(motion, hits=self.named(bodies))

    def named(self, bodies: frozenset[int]) -> frozenset[str]:
        """The movables and doors among ``bodies``, by name."""
        return frozenset(self._names[b] for b in bodies if b in self._names)

    def base_motion(self, region: RegionSpec) -> SweptMotion:
        """The route from the initial robot pose to ``region``'s standing pose, doors open."""
        segment = route_segment(
            self.base_planner, self.spec.robot.base, region.base_pose, self._all_open
        )
        bodies, _ = sweep(self.hands.collider, (segment,))
        return SweptMotion((segment,), self.named(bodies))

    def pick_record(self, obj: str, pose: ObjectPose) -> PickRecord:
        """Up to ``pick_samples`` picks of ``obj`` resting at ``pose``."""
        region_name = supporting_region(self.spec, pose)
        assert region_name is not None, f"'{obj}' rests on no region"
        region = self.spec.region(region_name)
        stand = region.base_pose
        spec = self.spec.object(obj)
        gap = self.sim.robot.gripper.opening
        window = grasp_window(spec, pose, stand, self.pitch_range, self.yaw_range, gap=gap)
        rng = np.random.default_rng(stable_seed(self.settings.seed, "pick", obj))
        motions: list[SweptMotion] = []
        grasp: Grasp | None = None
        object_pose = ((pose.x, pose.y, pose.z), yaw_quat(pose.yaw))
        draws = 0
        while window is not None and (
            draws < self.settings.pick_samples
            or (not motions and draws < self.settings.pick_draws_until_one)
        ):
            draws += 1
            pitch, yaw = sample_grasp_angles(rng, window.pitch_range, window.yaw_range)
            target = gripper_target(window.point, stand[2], pitch, yaw)
            this_grasp = Grasp.make(obj, *compose(invert(target), object_pose))
            for arm in self.hands.picks(stand, target, rng, self.settings.ik_attempts):
                self.sim.place_object(obj, pose)
                motion = self._sweep(arm.pick_segments(obj, this_grasp))
                self.sim.place_object(obj, pose)
                if motion is None:
                    continue  # through the static scene: the next lift height
                motions.append(replace(motion, hits=motion.hits - {obj}))
                if grasp is None:
                    grasp = this_grasp
                break
        return PickRecord(pose, region_name, grasp, wrap_angle(pose.yaw - stand[2]), tuple(motions))

    def placements(
        self, obj: str, grasp: Grasp, offset: float, region: RegionSpec, *, persist: bool = False
    ) -> tuple[PlacementSample, ...]:
        """Up to ``placements_per_region`` placements of ``obj`` held at ``grasp`` on
        ``region``, keeping the yaw ``offset`` from the standing pose; with ``persist``, drawn
        on while none is feasible (see :class:`PredicateSettings`)."""
        rng = np.random.default_rng(stable_seed(self.settings.seed, "place", obj, region.name))
        settings = self.settings
        draws = settings.placement_draws_until_one if persist else settings.placement_draws
        return self._draw(
            obj,
            grasp,
            offset,
            region,
            rng,
            settings.placements_per_region,
            (settings.placement_draws, draws),
        )

    def targeted(
        self,
        obj: str,
        grasp: Grasp,
        offset: float,
        direction: str,
        ref: str,
        ref_pose: ObjectPose,
        region: RegionSpec,
        *,
        persist: bool = False,
    ) -> tuple[PlacementSample, ...]:
        """Placements drawn until ``targeted_samples`` lie in ``direction`` of ``ref`` (at
        ``ref_pose`` on ``region``) with motions that do not touch ``ref``: for a relative
        position no plain placement landed in."""
        rng = np.random.default_rng(stable_seed(self.settings.seed, "target", obj, direction, ref))
        settings = self.settings
        draws = settings.targeted_draws_until_one if persist else settings.targeted_draws
        return self._draw(
            obj,
            grasp,
            offset,
            region,
            rng,
            settings.targeted_samples,
            (settings.targeted_draws, draws),
            lambda pose: (
                direction_between(region, pose, ref_pose) == direction
                and not self._overlaps(obj, pose, ref, ref_pose)
            ),
            clear_of=ref,
        )

    def _overlaps(self, obj: str, pose: ObjectPose, other: str, other_pose: ObjectPose) -> bool:
        """Would ``obj`` at ``pose`` stand in ``other`` at ``other_pose``? (A sample that does
        is no place beside ``other``; caught here before IK and the sweep are paid for.)"""
        return footprints_overlap(
            self.spec.object(obj),
            (pose.x, pose.y, pose.yaw),
            self.spec.object(other),
            (other_pose.x, other_pose.y, other_pose.yaw),
            slack=PENETRATION_TOLERANCE,
        )

    def _draw(
        self,
        obj: str,
        grasp: Grasp,
        offset: float,
        region: RegionSpec,
        rng: np.random.Generator,
        wanted: int,
        draws: tuple[int, int],
        keep: Callable[[ObjectPose], bool] = lambda pose: True,
        clear_of: str | None = None,
    ) -> tuple[PlacementSample, ...]:
        """Uniform placements, the ones ``keep`` accepts planned, until ``wanted`` have
        feasible motions (not touching ``clear_of``, if named), the object does not fit the
        region, or ``draws`` = (n, m) are spent: n draws, or m while none is feasible."""
        yaw = wrap_angle(region.base_pose[2] + offset)
        spec = self.spec.object(obj)
        samples: list[PlacementSample] = []
        for drawn in range(max(draws)):
            if len(samples) >= wanted or (samples and drawn >= draws[0]):
                break
            pose = draw_placement(spec, region, yaw, rng)
            if pose is None:
                break
            if not keep(pose):
                continue
            sample = self._placement_motion(obj, grasp, region, pose, rng, clear_of)
            if sample is not None:
                samples.append(sample)
        return tuple(samples)

    def _placement_motion(
        self,
        obj: str,
        grasp: Grasp,
        region: RegionSpec,
        pose: ObjectPose,
        rng: np.random.Generator,
        clear_of: str | None = None,
    ) -> PlacementSample | None:
        stand = region.base_pose
        original = self.sim.object_pose(obj)
        for arm in self.hands.places(
            stand, placing_hand(pose, grasp), rng, self.settings.ik_attempts
        ):
            motion = self._sweep(arm.place_segments(obj, grasp, pose), clear_of)
            self.sim.place_object(obj, _pose_of(original))
            if motion is not None:
                return PlacementSample(pose, replace(motion, hits=motion.hits - {obj}))
        return None


def _pose_of(pose3: Pose3) -> ObjectPose:
    (x, y, z), orn = pose3
    return ObjectPose.make(x, y, z, quat_yaw(orn))
