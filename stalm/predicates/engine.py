"""Geometric predicates of a State, computed with motion planning, with Appendix A's cache.

Literals: HandAvailable, RobotHolding(o), IsClosed(door), AtPosition(o, dir, ref),
PickOccludedBy(o, x) and PlaceOccludedBy(o, dir, ref, x); and, beyond the paper, the actions
no sampled motion can do whatever is moved: CannotPick(o) for a resting object, and
CannotPlace(o, dir, ref) for the held one (an object at rest may still be picked with a grasp
that makes the placement possible, so only the held object's grasp is final). The paper's
prompt leaves these out (:mod:`stalm.predicates.literals`); before giving up on an action the
samples are drawn on up to five times the operator's own tries
(:class:`~stalm.predicates.samples.PredicateSettings`).

Occlusion follows §3.2: the motion for an action is planned *ignoring movable objects* (base
path to the standing pose, grasp or placement by the operator's sampler, IK, arm motion) and
every movable object or closed door its swept volume touches is an occluder. Each action gets
a fixed number of statically feasible samples; the occluders reported are those of the sample
with the fewest (ties: the first), so an object counts as occluded only if no sampled motion
avoids everything. Draws come from a generator seeded by the action's own key, so the samples
of an action do not depend on what else was computed before.

Caching (Appendix A): every sampled motion keeps its swept collisions, and literals are a pure
function of those and of which objects are obstacles now. After PICK nothing is swept again
(the picked object stops being an obstacle and its placements are resampled for the grasp
actually taken); after OPEN nothing is swept (an open door stops being an obstacle); after
PLACE the moved object's own actions are resampled, and only motions that pass near its new
pose are swept again, against it alone. :meth:`PredicateEngine.update` equals
:meth:`PredicateEngine.compute` on the new state, literal for literal.

Placements beside a reference: :mod:`stalm.predicates.beside`.

Base paths start from the problem's initial robot pose, not the robot's current one, so the
literals do not depend on where the robot last stood: the robot changes rooms only through an
open door, and an open door occludes nothing.

A computation is bounded by a deadline (:mod:`stalm.predicates.deadline`), asked between
samples: once it has passed, :meth:`PredicateEngine.compute` and :meth:`PredicateEngine.update`
raise :exc:`~stalm.predicates.deadline.DeadlinePassed` and return nothing, so a partly
computed cache never passes for a state's predicates.

An engine built with ``occlusion=False`` computes only the symbolic literals (HandAvailable,
RobotHolding, IsClosed, AtPosition) and plans no motion at all: what a prompt without
occlusion predicates (Table 4's ablation) shows, at what that prompt really costs. The search
never reads occlusion literals, so nothing else needs them.
"""

from __future__ import annotations

from typing import Protocol

from stalm.motion.base_motion import BasePlanner
from stalm.motion.grasps import PITCH_RANGE, YAW_RANGE
from stalm.motion.manipulation import PARKED
from stalm.predicates.beside import beside, targeted_wanted
from stalm.predicates.cache import PredicateCache, fewest, forget_object, holds, resweep_near
from stalm.predicates.deadline import Deadline, DeadlinePassed, check
from stalm.predicates.forked import forked_map
from stalm.predicates.goals import goal_region
from stalm.predicates.literals import SCOPE_PREDICATE, GroundLiteral
from stalm.predicates.progress import Report, reported_map
from stalm.predicates.samples import (
    MotionSamples,
    PickRecord,
    PlacementSample,
    PredicateSettings,
)
from stalm.predicates.symbolic import add_symbolic
from stalm.world.problem import Problem
from stalm.world.scene import Sim
from stalm.world.spec import RegionSpec
from stalm.world.state import State


class ActionTuple(Protocol):
    """What the engine needs of a discrete action: its operator and arguments, as a tuple
    (``("pick", obj)``, ``("place", obj, dir, ref)``, ``("open", door)``).

    The actions themselves live in :mod:`stalm.domain`, a sibling layer predicates may not
    import (``pyproject.toml``'s import contract); every discrete action has ``as_tuple``."""

    def as_tuple(self) -> tuple[str, ...]: ...


class PredicateEngine:
    """Computes and updates the literals of states of one problem.

    ``occlusion`` says whether PickOccludedBy/PlaceOccludedBy are computed (the motion
    planning); without them only the symbolic literals are, for prompts that do not show
    occlusions.
    """

    def __init__(
        self,
        problem: Problem,
        sim: Sim,
        base_planner: BasePlanner,
        settings: PredicateSettings | None = None,
        *,
        occlusion: bool = True,
        grasp_ranges: tuple[tuple[float, float], tuple[float, float]] = (PITCH_RANGE, YAW_RANGE),
    ) -> None:
        self.occlusion = occlusion
        self.problem = problem
        self.spec = problem.spec
        self.sim = sim
        self.base_planner = base_planner
        self.settings = settings or PredicateSettings()
        self.samples = MotionSamples(self.spec, sim, base_planner, self.settings, grasp_ranges)
        self._extent = self.samples.hands.extent

    # ------------------------------------------------------------------ public
    def compute(
        self, state: State, deadline: Deadline | None = None, report: Report | None = None
    ) -> PredicateCache:
        """All literals of ``state`` from scratch; :exc:`DeadlinePassed` once ``deadline``
        (None: none) has passed between two samples. ``report`` hears how far it is."""
        if not self.occlusion:
            return PredicateCache(state=state, literals=self._symbolic(state))
        try:
            return self._compute(state, deadline, report)
        except DeadlinePassed:
            self._prepare_world(state)  # the sim as a finished computation leaves it
            raise

    def update(
        self,
        cache: PredicateCache,
        action: ActionTuple,
        state: State,
        deadline: Deadline | None = None,
        report: Report | None = None,
    ) -> PredicateCache:
        """The literals of ``state``, reached from ``cache.state`` by the feasible ``action``
        (a discrete action of :mod:`stalm.domain.actions`), ``cache`` unchanged;
        :exc:`DeadlinePassed` past ``deadline`` (None: none); ``report`` hears how far."""
        if not self.occlusion:
            return PredicateCache(state=state, literals=self._symbolic(state))
        if self.settings.relevant_only:  # the relevant set itself moves with the state
            return self.compute(state, deadline, report)
        try:
            return self._update(cache, action, state, deadline)
        except DeadlinePassed:
            self._prepare_world(state)
            raise

    def _compute(
        self, state: State, deadline: Deadline | None, report: Report | None = None
    ) -> PredicateCache:
        cache = PredicateCache(state=state, literals=frozenset())
        self._prepare_world(state)
        for region in self.spec.regions:
            check(deadline)
            cache.base[region.name] = self.samples.base_motion(region)
        if self.settings.relevant_only:
            self._relevant(cache, deadline)  # placements only at the goal
        else:
            self._sample_everything(cache, deadline, report)
        cache.literals = self._derive(cache, deadline, report)
        return cache

    def _sample_everything(
        self, cache: PredicateCache, deadline: Deadline | None, report: Report | None = None
    ) -> None:
        """Every pick, every placement on every region, and the placements beside each
        reference that no plain placement lands at: independent samples, shared among
        ``settings.workers`` processes (:mod:`stalm.predicates.forked`)."""
        state, workers = cache.state, self.settings.workers

        def pick(name: str) -> PickRecord:
            check(deadline)
            return self.samples.pick_record(name, state.pose(name))

        names = [name for name, _ in state.poses]
        picks = reported_map(pick, names, workers, report, "picks")
        cache.picks.update(zip(names, picks, strict=True))
        self._refresh_grasps(cache)
        pairs = [(obj, region) for obj in cache.grasps for region in self.spec.regions]
        place = lambda pair: self._placements(cache, pair[0], pair[1], deadline)  # noqa: E731
        placed = reported_map(place, pairs, workers, report, "placements")
        for (obj, region), samples in zip(pairs, placed, strict=True):
            cache.placements[(obj, region.name)] = samples
        if workers == 1:
            return  # the derivation draws the placements beside references as it meets them
        wanted = sorted(targeted_wanted(self.problem, cache), key=lambda key: key[:3])
        targeted = forked_map(lambda key: self._targeted(cache, *key, deadline), wanted, workers)
        for (obj, direction, ref, _), samples in zip(wanted, targeted, strict=True):
            cache.targeted[(obj, direction, ref)] = samples

    def _relevant(self, cache: PredicateCache, deadline: Deadline | None) -> None:
        """Picks of the goal's objects, of what occludes picking them or placing them at their
        goal, and recursively of what occludes picking those (a closed door opens, so only
        objects are followed)."""
        state = cache.state
        obstacles = self._obstacles(state)
        movable = {name for name, _ in state.poses}
        goal = self.problem.goal
        queue = [g.obj for g in goal] + [g.ref for g in goal if g.direction != "on"]
        seen: set[str] = set()
        while queue:
            obj = queue.pop(0)
            if obj in seen or (
                not state.has_pose(obj) and (state.held is None or state.held.obj != obj)
            ):
                continue
            seen.add(obj)
            occluders: set[str] = set()
            if state.has_pose(obj):
                check(deadline)
                record = self.samples.pick_record(obj, state.pose(obj))
                cache.picks[obj] = record
                base = cache.base[record.region].hits
                best = fewest((m.hits | base) & (obstacles - {obj}) for m in record.motions)
                occluders |= set(best or ())
            self._refresh_grasps(cache)
            for target in (g for g in goal if g.obj == obj and obj in cache.grasps):
                region = goal_region(self.spec, state, target.direction, target.ref)
                if region is None:
                    continue
                samples = cache.placements.get((obj, region.name))
                if samples is None:
                    samples = self._placements(cache, obj, region, deadline)
                    cache.placements[(obj, region.name)] = samples
                if target.direction != "on":
                    samples = self._targeted(
                        cache, obj, target.direction, target.ref, region, deadline
                    )
                base = cache.base[region.name].hits
                best = fewest((s.motion.hits | base) & (obstacles - {obj}) for s in samples)
                occluders |= set(best or ())
            queue.extend(sorted(occluders & movable))
        cache.relevant = frozenset(seen)

    def _update(
        self, cache: PredicateCache, action: ActionTuple, state: State, deadline: Deadline | None
    ) -> PredicateCache:
        new = PredicateCache(
            state=state,
            literals=frozenset(),
            base=dict(cache.base),
            picks=dict(cache.picks),
            placements=dict(cache.placements),
            targeted=dict(cache.targeted),
        )
        self._prepare_world(state)
        operator, *arguments = action.as_tuple()
        if operator == "pick":
            obj = arguments[0]
            new.picks.pop(obj, None)
            forget_object(new, obj)
            self._refresh_grasps(new)
            self._resample_placements_of(new, obj, deadline)
        elif operator == "place":
            obj = arguments[0]
            forget_object(new, obj)
            resweep_near(
                new, self.samples.hands.collider, obj, state.pose(obj), self._extent[obj], deadline
            )
            check(deadline)
            new.picks[obj] = self.samples.pick_record(obj, state.pose(obj))
            self._refresh_grasps(new)
            self._resample_placements_of(new, obj, deadline)
            new.targeted = {k: v for k, v in new.targeted.items() if k[2] != obj}
        else:
            # an open door is no obstacle: the derivation below stops counting it
            self._refresh_grasps(new)
        new.literals = self._derive(new, deadline)
        new.swept_motions += cache.swept_motions
        return new

    # ------------------------------------------------------------------ world
    def _prepare_world(self, state: State) -> None:
        """Set the sim to ``state`` with the held object parked out of the way."""
        self.sim.set_state(state)
        if state.held is not None:
            self.sim.attach(None)
            self.sim.place_object(state.held.obj, PARKED)

    def _obstacles(self, state: State) -> frozenset[str]:
        closed = frozenset(d.name for d in self.spec.doors if not state.is_open(d.name))
        return frozenset(name for name, _ in state.poses) | closed

    # ------------------------------------------------------------------ samples
    def _refresh_grasps(self, cache: PredicateCache) -> None:
        """The grasp each object's placements use: the one in hand, or its first feasible pick."""
        cache.grasps = {}
        held = cache.state.held
        if held is not None:
            cache.grasps[held.obj] = (held, cache.state.held_yaw_offset)
        for obj, record in cache.picks.items():
            if record.grasp is not None:
                cache.grasps[obj] = (record.grasp, record.yaw_offset)

    def _placements(
        self, cache: PredicateCache, obj: str, region: RegionSpec, deadline: Deadline | None
    ) -> tuple[PlacementSample, ...]:
        check(deadline)
        grasp, offset = cache.grasps[obj]
        return self.samples.placements(obj, grasp, offset, region, persist=holds(cache, obj))

    def _targeted(
        self,
        cache: PredicateCache,
        obj: str,
        direction: str,
        ref: str,
        region: RegionSpec,
        deadline: Deadline | None,
    ) -> tuple[PlacementSample, ...]:
        """Placements in ``direction`` of ``ref``, sampled once per state the key holds in."""
        key = (obj, direction, ref)
        if key not in cache.targeted:
            check(deadline)
            grasp, offset = cache.grasps[obj]
            cache.targeted[key] = self.samples.targeted(
                obj,
                grasp,
                offset,
                direction,
                ref,
                cache.state.pose(ref),
                region,
                persist=holds(cache, obj),
            )
        return cache.targeted[key]

    # ------------------------------------------------------------------ updates
    def _resample_placements_of(
        self, cache: PredicateCache, obj: str, deadline: Deadline | None
    ) -> None:
        cache.placements = {k: v for k, v in cache.placements.items() if k[0] != obj}
        cache.targeted = {k: v for k, v in cache.targeted.items() if k[0] != obj}
        if obj in cache.grasps:
            for region in self.spec.regions:
                cache.placements[(obj, region.name)] = self._placements(
                    cache, obj, region, deadline
                )

    # ------------------------------------------------------------------ literals
    def _symbolic(self, state: State) -> frozenset[GroundLiteral]:
        """The literals that need no motion planning: hand, doors, AtPosition."""
        literals: set[GroundLiteral] = set()
        add_symbolic(self.spec, state, literals)
        return frozenset(literals)

    def _derive(
        self, cache: PredicateCache, deadline: Deadline | None, report: Report | None = None
    ) -> frozenset[GroundLiteral]:
        state = cache.state
        literals: set[GroundLiteral] = set()
        regions_of = add_symbolic(self.spec, state, literals)
        obstacles = self._obstacles(state)
        cache.unreachable = set()
        if cache.relevant is not None:
            literals.update(GroundLiteral(SCOPE_PREDICATE, (obj,)) for obj in cache.relevant)
        for obj, record in cache.picks.items():
            base = cache.base[record.region].hits
            best = fewest((m.hits | base) & (obstacles - {obj}) for m in record.motions)
            if best is None:
                cache.unreachable.add(f"pick {obj}")
                literals.add(GroundLiteral("CannotPick", (obj,)))
                continue
            literals.update(GroundLiteral("PickOccludedBy", (obj, x)) for x in best)
        for done, obj in enumerate(cache.grasps):
            if report is not None:
                report("occlusions", done, len(cache.grasps))
            for region in self.spec.regions:
                if cache.relevant is not None and (obj, region.name) not in cache.placements:
                    continue  # not at the goal: left to Concretize
                samples = cache.placements.get((obj, region.name), ())
                self._place_literals(
                    cache, literals, obstacles, obj, "on", region.name, region, samples
                )
                for direction, ref, matching in beside(
                    self.problem, cache, regions_of, obj, region, samples
                ):
                    if not matching:
                        matching = self._targeted(cache, obj, direction, ref, region, deadline)
                    self._place_literals(
                        cache, literals, obstacles, obj, direction, ref, region, matching
                    )
        self._prepare_world(state)
        return frozenset(literals)

    def _place_literals(
        self,
        cache: PredicateCache,
        literals: set[GroundLiteral],
        obstacles: frozenset[str],
        obj: str,
        direction: str,
        ref: str,
        region: RegionSpec,
        samples: tuple[PlacementSample, ...],
    ) -> None:
        base = cache.base[region.name].hits
        best = fewest((s.motion.hits | base) & (obstacles - {obj}) for s in samples)
        if best is None:
            cache.unreachable.add(f"place {obj} {direction} {ref}")
            if holds(cache, obj):  # an object at rest may be picked with another grasp
                literals.add(GroundLiteral("CannotPlace", (obj, direction, ref)))
            return
        literals.update(GroundLiteral("PlaceOccludedBy", (obj, direction, ref, x)) for x in best)
