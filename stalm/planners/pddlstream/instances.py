"""Stream instances of PDDLStream's adaptive algorithm: what they are, their optimistic
outputs, and their evaluation on the domain's geometry.

A *stream instance* is a stream applied to input objects (:class:`StreamKey`). Within a
complexity limit every enabled instance gets one optimistic output object certifying its facts
(:meth:`Streams.instantiate`); an instance a plan needs is called for real
(:meth:`Streams.evaluate`), and its record says how often it was called, whether it failed
(disabled until the next failed search) and whether it can never produce anything
(exhausted). Which instances to evaluate, and when, is the loop's (:mod:`.adaptive`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from stalm.domain.actions import RELATIVE_DIRECTIONS
from stalm.errors import StalmError
from stalm.planners.pddlstream.knowledge import Knowledge
from stalm.planners.pddlstream.pddl_text import Fact
from stalm.planners.pddlstream.values import GRASP, MOTION, POSE, is_optimistic, optimistic_name

OUT = "?out"
"""Placeholder for an instance's output object in the facts it certifies."""


@dataclass(frozen=True, order=True)
class StreamKey:
    """A stream instance: the stream's name and its input objects."""

    stream: str
    inputs: tuple[str, ...]

    def __str__(self) -> str:
        return f"{self.stream}({', '.join(self.inputs)})"


@dataclass
class InstanceRecord:
    """What is known about one stream instance over real inputs."""

    calls: int = 0
    successes: int = 0
    disabled: bool = False
    exhausted: bool = False
    """It can never produce anything (e.g. the object does not fit on the region)."""


@dataclass(frozen=True)
class Optimistic:
    """An optimistic output object: what instance it stands for and the facts it certifies."""

    name: str
    kind: str
    key: StreamKey
    complexity: int
    facts: tuple[Fact, ...]


@dataclass(frozen=True)
class Outcome:
    """One stream call: the real object it produced, or None."""

    produced: str | None
    exhausted: bool = False


@dataclass
class Streams:
    """The stream instances' records and their evaluation on the knowledge's geometry."""

    knowledge: Knowledge
    movables: tuple[str, ...]
    regions: tuple[str, ...]
    doors: tuple[str, ...]
    records: dict[StreamKey, InstanceRecord] = field(default_factory=dict)
    calls: int = 0
    failures: int = 0
    seconds: float = 0.0
    """Time spent sampling and planning motions (the tests of new objects excluded)."""

    # ------------------------------------------------------------------ instantiation
    def instantiate(self, limit: int) -> dict[str, Optimistic]:
        """Optimistic outputs of every enabled instance within the complexity ``limit``."""
        k = self.knowledge
        out: dict[str, Optimistic] = {}
        counters = {POSE: 0, GRASP: 0, MOTION: 0}

        def complexity(name: str) -> int:
            return out[name].complexity if name in out else 0

        def optimistic(kind: str, obj: str) -> list[str]:
            return [n for n, o in out.items() if o.kind == kind and o.key.inputs[0] == obj]

        def offer(stream: str, inputs: tuple[str, ...], kind: str, facts: list[Fact]) -> None:
            key = StreamKey(stream, inputs)
            calls = 0
            if not any(is_optimistic(x) for x in inputs):
                record = self.records.get(key)
                if record is not None:
                    if record.disabled or record.exhausted:
                        return
                    calls = record.calls
            level = max((complexity(x) for x in inputs), default=0) + calls
            if level > limit:
                return
            name = optimistic_name(kind, counters[kind])
            counters[kind] += 1
            certified = tuple(tuple(name if a == OUT else a for a in f) for f in facts)
            out[name] = Optimistic(name, kind, key, level + 1, certified)

        for obj in self.movables:
            offer("sample-grasp", (obj,), GRASP, [])
        for obj in self.movables:
            for region in self.regions:
                if k.geometry.fits(obj, region):
                    offer("sample-pose", (obj, region), POSE, [("Supported", obj, OUT, region)])
        for obj in self.movables:
            for direction in RELATIVE_DIRECTIONS:
                for ref_pose, ref in k.poses.items():
                    if ref.obj == obj or not k.geometry.fits(obj, ref.region):
                        continue
                    offer(
                        "sample-rel-pose",
                        (obj, direction, ref.obj, ref_pose),
                        POSE,
                        [
                            ("Supported", obj, OUT, ref.region),
                            ("Rel", obj, OUT, direction, ref.obj, ref_pose),
                        ],
                    )
        for stream, predicate in (("plan-pick", "PickKin"), ("plan-place", "PlaceKin")):
            for obj in self.movables:
                grasps = k.grasps_of(obj) + optimistic(GRASP, obj)
                for pose in k.poses_of(obj) + optimistic(POSE, obj):
                    for grasp in grasps:
                        offer(
                            stream, (obj, pose, grasp), MOTION, [(predicate, obj, pose, grasp, OUT)]
                        )
        for door in self.doors:
            offer("plan-open", (door,), MOTION, [("OpenKin", door, OUT)])
        return out

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, key: StreamKey, rng: np.random.Generator) -> Outcome:
        """Call the instance ``key`` (all inputs real) once; record what happened."""
        record = self.records.setdefault(key, InstanceRecord())
        if record.exhausted:
            return Outcome(None, exhausted=True)
        tick = time.monotonic()
        tests_before = self.knowledge.test_seconds
        record.calls += 1
        self.calls += 1
        outcome = self._call(key, rng)
        tests = self.knowledge.test_seconds - tests_before
        self.seconds += time.monotonic() - tick - tests
        if outcome.produced is None:
            self.failures += 1
            record.disabled = True
            record.exhausted = outcome.exhausted
        else:
            record.successes += 1
        return outcome

    def _call(self, key: StreamKey, rng: np.random.Generator) -> Outcome:
        k = self.knowledge
        geometry = k.geometry
        args = key.inputs
        if key.stream == "sample-grasp":
            grasp = geometry.sample_grasp(args[0], rng)
            return Outcome(None, exhausted=True) if grasp is None else Outcome(k.add_grasp(grasp))
        if key.stream == "sample-pose":
            pose = geometry.sample_pose(args[0], args[1], rng)
            return Outcome(None, exhausted=True) if pose is None else Outcome(k.add_pose(pose))
        if key.stream == "sample-rel-pose":
            pose = geometry.sample_rel_pose(args[0], args[1], k.poses[args[3]], rng)
            return Outcome(None) if pose is None else Outcome(k.add_pose(pose))
        if key.stream in ("plan-pick", "plan-place"):
            plan = geometry.plan_pick if key.stream == "plan-pick" else geometry.plan_place
            motion = plan(k.poses[args[1]], k.grasps[args[2]], (args[1], args[2]), rng)
            return Outcome(None) if motion is None else Outcome(k.add_motion(motion))
        if key.stream == "plan-open":
            motion = geometry.plan_open(args[0], rng)
            return Outcome(None) if motion is None else Outcome(k.add_motion(motion))
        raise StalmError(f"unknown stream '{key.stream}'")

    def reenable(self) -> int:
        """Re-enable every disabled (not exhausted) instance; how many there were."""
        count = 0
        for record in self.records.values():
            if record.disabled and not record.exhausted:
                record.disabled = False
                count += 1
        return count
