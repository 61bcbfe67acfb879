"""A plan in robot time: when each action's base drive and arm motion run, and when the hand
grasps, releases or opens a door.

An action executes as the planner checked it: the base drives its path with the arm folded,
then the arm (lift and joints) moves through its waypoints at the standing pose. Each motion is
timed under the robot's limits (:mod:`stalm.motion.timing`), one after another from the plan's
start. Grasping is kinematic: the object is attached when the arm reaches the grasp
configuration, released at the placing one, and the door opens at the handle's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.errors import StalmError
from stalm.motion.timing import TimedMotion, time_base_path, time_waypoints
from stalm.world.robot_limits import RobotLimits

GRASP, RELEASE, OPEN_DOOR = "grasp", "release", "open_door"
"""The kinds of :class:`PlanEvent`."""


@dataclass(frozen=True)
class ActionTiming:
    """One action's two motions in robot time: the base drive from ``start``, then the arm
    motion, which reaches its waypoint ``key_waypoint`` (the grasp, placing or handle
    configuration) when the action's event happens."""

    action: Action
    start: float
    base: TimedMotion
    arm: TimedMotion
    key_waypoint: int

    @property
    def arm_start(self) -> float:
        return self.start + self.base.duration

    @property
    def end(self) -> float:
        return self.arm_start + self.arm.duration

    @property
    def event_time(self) -> float:
        return self.arm_start + self.arm.waypoint_times[self.key_waypoint]


@dataclass(frozen=True)
class PlanEvent:
    """A grasp, release or door opening: its time (seconds from the plan's start), the index
    of the action, its kind and the object or door it acts on."""

    time: float
    action: int
    kind: str
    name: str


@dataclass(frozen=True)
class PlanSchedule:
    actions: tuple[ActionTiming, ...]
    limits: RobotLimits

    @property
    def duration(self) -> float:
        return self.actions[-1].end if self.actions else 0.0

    def times_of(self, points: Sequence[tuple[int, str, int, float]]) -> list[float]:
        """The robot time at each point of the plan, given as (action, motion, move,
        fraction): ``fraction`` of the way through straight move ``move`` of the action's
        ``base`` or ``arm`` motion, or the action's ``end``; action -1 is the plan's start.
        The points of one move are found together (one bisection for all of them)."""
        times = [0.0] * len(points)
        groups: dict[tuple[int, str, int], list[int]] = {}
        for index, (action, motion, move, _) in enumerate(points):
            if action >= 0 and motion == "end":
                times[index] = self.actions[action].end
            elif action >= 0:
                groups.setdefault((action, motion, move), []).append(index)
        for (action, motion, move), indices in groups.items():
            timing = self.actions[action]
            start, timed = (
                (timing.start, timing.base) if motion == "base" else (timing.arm_start, timing.arm)
            )
            found = timed.time_at(move, [points[i][3] for i in indices])
            for index, time in zip(indices, found, strict=True):
                times[index] = start + float(time)
        return times

    @property
    def events(self) -> tuple[PlanEvent, ...]:
        events = []
        for index, timing in enumerate(self.actions):
            kind = _event_kind(timing.action)
            name = timing.action.discrete.as_tuple()[1]
            events.append(PlanEvent(timing.event_time, index, kind, name))
        return tuple(events)


def _event_kind(action: Action) -> str:
    params = action.params
    if isinstance(params, PickParams):
        return GRASP
    if isinstance(params, PlaceParams):
        return RELEASE
    return OPEN_DOOR


def key_configuration(action: Action) -> tuple[float, ...]:
    """The configuration at which ``action`` acts: the grasp, placing or handle one."""
    params = action.params
    if isinstance(params, PickParams):
        return params.grasp_conf
    if isinstance(params, PlaceParams):
        return params.place_conf
    assert isinstance(params, OpenParams)
    return params.handle_conf


def schedule_plan(actions: Sequence[Action], limits: RobotLimits) -> PlanSchedule:
    """Time every motion of ``actions`` under ``limits``, one after another from 0."""
    timings = []
    clock = 0.0
    for action in actions:
        params = action.params
        base = time_base_path(params.base_path, limits.base)
        arm = time_waypoints(params.arm_waypoints, limits.arm)
        conf = key_configuration(action)
        if conf not in params.arm_waypoints:
            raise StalmError(
                f"{action.discrete}: its arm waypoints do not pass through the configuration "
                "it grasps, places or pulls the handle at: no time for its event"
            )
        key = params.arm_waypoints.index(conf)
        timing = ActionTiming(action, clock, base, arm, key)
        timings.append(timing)
        clock = timing.end
    return PlanSchedule(tuple(timings), limits)
