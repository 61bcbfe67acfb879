"""Every real PDDL object computed so far, and the static facts certified about them.

Objects only ever accumulate: a pose, grasp or motion once sampled stays for the rest of the
trial, because PDDLStream cannot know that a sample that failed in one context is useless in
every other (a grasp blocked by an occluder works once the occluder is moved). Test streams
are evaluated eagerly: whenever a pose or motion is added, it is tested against every known
motion or pose (``Collides``), and new poses get their relations to the poses on the same
region (``Rel``). The paper's §4.3 counts this growth as the method's weakness.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from stalm.planners.pddlstream.pddl_text import Fact
from stalm.planners.pddlstream.streams import StreamGeometry
from stalm.planners.pddlstream.values import (
    GRASP,
    MOTION,
    POSE,
    GraspValue,
    MotionValue,
    PoseValue,
    real_name,
)
from stalm.world.relations import direction_between
from stalm.world.state import ObjectPose


@dataclass
class Knowledge:
    """Real objects by name and the facts the streams certified."""

    geometry: StreamGeometry
    poses: dict[str, PoseValue] = field(default_factory=dict)
    grasps: dict[str, GraspValue] = field(default_factory=dict)
    motions: dict[str, MotionValue] = field(default_factory=dict)
    facts: set[Fact] = field(default_factory=set)
    dead: set[str] = field(default_factory=set)
    """Motions whose execution failed with nothing to blame: no longer usable."""
    test_seconds: float = 0.0
    _pose_names: dict[tuple[str, ObjectPose], str] = field(default_factory=dict)

    # ------------------------------------------------------------------ queries
    @property
    def object_count(self) -> int:
        return len(self.poses) + len(self.grasps) + len(self.motions)

    def counts(self) -> dict[str, int]:
        return {POSE: len(self.poses), GRASP: len(self.grasps), MOTION: len(self.motions)}

    def pose_name(self, obj: str, pose: ObjectPose) -> str | None:
        return self._pose_names.get((obj, pose))

    def poses_of(self, obj: str) -> list[str]:
        return [name for name, value in self.poses.items() if value.obj == obj]

    def grasps_of(self, obj: str) -> list[str]:
        return [name for name, value in self.grasps.items() if value.obj == obj]

    def usable_motions(self) -> list[str]:
        return [name for name in self.motions if name not in self.dead]

    # ------------------------------------------------------------------ additions
    def add_pose(self, value: PoseValue) -> str:
        """Register a pose (the same pose of the same object twice is one object)."""
        known = self._pose_names.get((value.obj, value.pose))
        if known is not None:
            return known
        name = real_name(POSE, len(self.poses))
        tick = time.monotonic()
        self.poses[name] = value
        self._pose_names[(value.obj, value.pose)] = name
        self.facts.add(("Supported", value.obj, name, value.region))
        region = self.geometry.spec.region(value.region)
        for other_name, other in self.poses.items():
            if other.obj == value.obj or other.region != value.region:
                continue
            there = direction_between(region, value.pose, other.pose)
            back = direction_between(region, other.pose, value.pose)
            self.facts.add(("Rel", value.obj, name, there, other.obj, other_name))
            self.facts.add(("Rel", other.obj, other_name, back, value.obj, name))
        for motion_name, motion in self.motions.items():
            if motion.subject != value.obj and self.geometry.collides(motion, value):
                self.facts.add(("Collides", motion_name, value.obj, name))
        self.test_seconds += time.monotonic() - tick
        return name

    def add_grasp(self, value: GraspValue) -> str:
        name = real_name(GRASP, len(self.grasps))
        self.grasps[name] = value
        return name

    def add_motion(self, value: MotionValue) -> str:
        """Register a motion with its kinematic fact, the doors it crosses and its collisions
        with every known pose of every other object."""
        name = real_name(MOTION, len(self.motions))
        tick = time.monotonic()
        self.motions[name] = value
        self.facts.add(self.kin_fact(name))
        for door in sorted(value.crosses):
            self.facts.add(("Crosses", name, door))
        for pose_name, pose in self.poses.items():
            if pose.obj != value.subject and self.geometry.collides(value, pose):
                self.facts.add(("Collides", name, pose.obj, pose_name))
        self.test_seconds += time.monotonic() - tick
        return name

    def kin_fact(self, motion: str) -> Fact:
        value = self.motions[motion]
        if value.kind == "open":
            return ("OpenKin", value.subject, motion)
        assert value.pose is not None and value.grasp is not None
        predicate = "PickKin" if value.kind == "pick" else "PlaceKin"
        return (predicate, value.subject, value.pose, value.grasp, motion)

    def retire(self, motion: str) -> None:
        """A motion that failed in execution for no known reason is not offered again."""
        self.dead.add(motion)
        self.facts.discard(self.kin_fact(motion))
