"""PDDLStream's adaptive algorithm: optimistic objects, stream plans, disabling and complexity.

One iteration (Garrett et al., 2020, "adaptive"; simplified as the module notes say):

1. **Optimistic instantiation.** Every stream instance whose inputs exist (real objects, or
   optimistic outputs of other instances) and whose *complexity* is within the current limit
   gets one optimistic output object (``opt_pose_4``...) certifying its facts optimistically.
   Complexity of an instance = the largest complexity of its inputs + how often it has been
   called; an output's complexity is its instance's plus one; real objects have complexity 0.
   Disabled and exhausted instances get no output. Optimistic motions are assumed to collide
   with nothing (their tests are not evaluated yet).
2. **Search.** Fast Downward plans over real plus optimistic objects; an action's cost is
   1 for a real motion and 1 + complexity for an optimistic one (stream effort), so values
   already computed are preferred.
3. **No plan:** raise the complexity limit by one and re-enable every disabled instance.
4. **Plan with optimistic objects:** its *stream plan* is the instances producing them, inputs
   first, in the order the plan uses them. They are evaluated in that order, each optimistic
   input replaced by the real object its instance just produced (PDDLStream's binding). The
   first failure disables that instance and ends the iteration; a disabled instance is not
   offered again until a search fails (step 3), so the planner first tries every other
   option. Success or failure, each call raises the instance's complexity, so an instance
   called often is offered only once the limit has grown (an exponential-free version of
   PDDLStream's revisiting). Every output becomes a real object for the rest of the trial.
5. **Plan with real objects only:** the caller executes it.

Simplified relative to PDDLStream: no skeleton queue and no search/sample time ratio (a stream
plan is evaluated once, greedily, right after the search that produced it); test streams are
evaluated eagerly for every real motion and pose instead of lazily; ``sample-rel-pose`` takes
only real reference poses (no optimistic-on-optimistic relative placements).
"""

from __future__ import annotations

import subprocess
import tempfile
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stalm.domain.actions import RELATIVE_DIRECTIONS
from stalm.errors import StalmError
from stalm.planners.pddlstream.knowledge import Knowledge
from stalm.planners.pddlstream.pddl_text import DOMAIN_PDDL, Fact, problem_pddl
from stalm.planners.pddlstream.values import (
    GRASP,
    MOTION,
    POSE,
    is_optimistic,
    optimistic_name,
)
from stalm.planners.symbolic import read_plan_steps, search_task, translate_task

OUT = "?out"
"""Placeholder for an instance's output object in the facts it certifies."""

SEARCH = "lazy_wastar([ff()], preferred=[ff()], w=2)"
"""Fast Downward's search: weighted A* (w = 2) with the FF heuristic and preferred operators;
costs matter (real values are cheaper than optimistic ones), so not plain greedy search."""


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


@dataclass(frozen=True)
class AdaptiveSettings:
    initial_complexity: int = 1
    """Complexity limit of the first search (1: each stream once on the initial objects)."""
    search: str = SEARCH
    memory_limit_mb: int = 2048
    """Cap on one Fast Downward search (the machine is shared; PDDLStream runs it alike)."""


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
                poses = k.poses_of(obj) + [
                    n for n, o in out.items() if o.kind == POSE and o.key.inputs[0] == obj
                ]
                grasps = k.grasps_of(obj) + [
                    n for n, o in out.items() if o.kind == GRASP and o.key.inputs[0] == obj
                ]
                for pose in poses:
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
            return Outcome(k.add_grasp(geometry.sample_grasp(args[0], rng)))
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


def stream_plan(
    steps: Sequence[tuple[str, ...]], optimistic: dict[str, Optimistic]
) -> list[Optimistic]:
    """The instances behind the optimistic objects a plan uses: inputs first, in plan order."""
    order: list[Optimistic] = []
    seen: set[str] = set()

    def visit(name: str) -> None:
        if name in seen or name not in optimistic:
            return
        seen.add(name)
        for item in optimistic[name].key.inputs:
            visit(item)
        order.append(optimistic[name])

    for step in steps:
        for arg in step[1:]:
            visit(arg)
    return order


@dataclass(frozen=True)
class SearchResult:
    """One Fast Downward call: the plan (None if none was found) and where the time went."""

    steps: tuple[tuple[str, ...], ...] | None
    translate_s: float
    search_s: float
    reason: str = ""


def fast_downward(
    problem: str, search: str, time_limit_s: float, memory_limit_mb: int | None = None
) -> SearchResult:
    """Translate and search ``problem`` over :data:`DOMAIN_PDDL` within ``time_limit_s``
    (and ``memory_limit_mb`` for the search)."""
    with tempfile.TemporaryDirectory(prefix="stalm-pddlstream-") as folder:
        work = Path(folder)
        (work / "domain.pddl").write_text(DOMAIN_PDDL)
        (work / "problem.pddl").write_text(problem)
        tick = time.monotonic()
        try:
            translate_task(work, max(time_limit_s, 0.1))
        except subprocess.TimeoutExpired:
            return SearchResult(None, time.monotonic() - tick, 0.0, "translator time limit")
        translated = time.monotonic()
        remaining = time_limit_s - (translated - tick)
        if remaining <= 0:
            return SearchResult(None, translated - tick, 0.0, "time limit")
        try:
            run = search_task(work, search, remaining, memory_limit_mb)
        except subprocess.TimeoutExpired:
            return SearchResult(
                None, translated - tick, time.monotonic() - translated, "search time limit"
            )
        searched = time.monotonic()
        if run.plan is None:
            output = run.output.lower()
            reason = "no plan"
            if "unsolvable" in output:
                reason = "unsolvable"
            elif "memory" in output:
                reason = "search memory limit"
            return SearchResult(None, translated - tick, searched - translated, reason)
        return SearchResult(read_plan_steps(run.plan), translated - tick, searched - translated)


def optimistic_problem(
    knowledge: Knowledge,
    optimistic: dict[str, Optimistic],
    names: dict[str, tuple[str, ...]],
    fluents: Iterable[Fact],
    goal: Iterable[Fact],
) -> str:
    """The PDDL problem over real and optimistic objects from the current fluent facts."""
    objects: dict[str, list[str]] = {kind: list(values) for kind, values in names.items()}
    objects[POSE] = list(knowledge.poses) + [n for n, o in optimistic.items() if o.kind == POSE]
    objects[GRASP] = list(knowledge.grasps) + [n for n, o in optimistic.items() if o.kind == GRASP]
    motions = knowledge.usable_motions()
    objects[MOTION] = motions + [n for n, o in optimistic.items() if o.kind == MOTION]
    costs = {m: 1 for m in motions}
    costs.update({n: 1 + o.complexity for n, o in optimistic.items() if o.kind == MOTION})
    facts = sorted(knowledge.facts) + [f for o in optimistic.values() for f in o.facts]
    return problem_pddl(objects, [*sorted(fluents), *facts], costs, goal)


@dataclass(frozen=True)
class Iteration:
    """One adaptive iteration: what it did (``record``), and the plan when it uses real
    objects only (the caller executes it)."""

    record: dict[str, Any]
    plan: tuple[tuple[str, ...], ...] | None


@dataclass
class Adaptive:
    """The adaptive loop's state across iterations: streams, knowledge, complexity limit."""

    streams: Streams
    names: dict[str, tuple[str, ...]]
    """The problem's own objects by PDDL type (movables, regions, doors)."""
    goal: tuple[Fact, ...]
    settings: AdaptiveSettings = field(default_factory=AdaptiveSettings)
    limit: int = -1
    fd_seconds: float = 0.0
    translate_seconds: float = 0.0

    def __post_init__(self) -> None:
        if self.limit < 0:
            self.limit = self.settings.initial_complexity

    @property
    def knowledge(self) -> Knowledge:
        return self.streams.knowledge

    def iterate(
        self, fluents: Iterable[Fact], rng: np.random.Generator, deadline: float
    ) -> Iteration:
        """Search the optimistic problem from ``fluents``; evaluate the plan's stream plan or
        return the plan if it needs no stream; on no plan raise the limit and re-enable."""
        knowledge = self.knowledge
        optimistic = self.streams.instantiate(self.limit)
        text = optimistic_problem(knowledge, optimistic, self.names, fluents, self.goal)
        own = sum(len(v) for v in self.names.values())
        record: dict[str, Any] = {
            "complexity_limit": self.limit,
            "real_objects": knowledge.object_count,
            "optimistic_objects": len(optimistic),
            "pddl_objects": knowledge.object_count + len(optimistic) + own,
        }
        search = fast_downward(
            text,
            self.settings.search,
            deadline - time.monotonic(),
            self.settings.memory_limit_mb,
        )
        self.fd_seconds += search.translate_s + search.search_s
        self.translate_seconds += search.translate_s
        record["fd_translate_s"] = round(search.translate_s, 3)
        record["fd_search_s"] = round(search.search_s, 3)
        if search.steps is None:
            record["result"] = search.reason
            if time.monotonic() < deadline:
                record["reenabled"] = self.streams.reenable()
                self.limit += 1
            return Iteration(record, None)
        record["plan_length"] = len(search.steps)
        to_evaluate = stream_plan(search.steps, optimistic)
        if not to_evaluate:
            record["result"] = "plan over real objects"
            return Iteration(record, search.steps)
        record.update(self._evaluate(to_evaluate, rng, deadline))
        return Iteration(record, None)

    def _evaluate(
        self, to_evaluate: list[Optimistic], rng: np.random.Generator, deadline: float
    ) -> dict[str, Any]:
        """Evaluate a stream plan in order, binding optimistic inputs to the real outputs
        just produced; stop at the first failure (that instance is now disabled)."""
        tick = time.monotonic()
        sampling_before = self.streams.seconds
        tests_before = self.knowledge.test_seconds
        binding: dict[str, str] = {}
        evaluated = 0
        failed: str | None = None
        for item in to_evaluate:
            if time.monotonic() >= deadline:
                break
            inputs = tuple(binding.get(x, x) for x in item.key.inputs)
            if any(is_optimistic(x) for x in inputs):
                raise StalmError(f"stream plan out of order at {item.key}")
            key = StreamKey(item.key.stream, inputs)
            outcome = self.streams.evaluate(key, rng)
            evaluated += 1
            if outcome.produced is None:
                failed = str(key)
                break
            binding[item.name] = outcome.produced
        return {
            "result": "stream failure" if failed else "streams evaluated",
            "stream_plan": len(to_evaluate),
            "evaluated": evaluated,
            "failed": failed,
            "sampling_s": round(self.streams.seconds - sampling_before, 3),
            "tests_s": round(self.knowledge.test_seconds - tests_before, 3),
            "stream_plan_s": round(time.monotonic() - tick, 3),
        }
