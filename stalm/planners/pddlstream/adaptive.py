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

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from stalm.errors import StalmError
from stalm.json_object import JsonObject, record_json
from stalm.planners.pddlstream.downward import SEARCH, fast_downward
from stalm.planners.pddlstream.instances import Optimistic, StreamKey, Streams
from stalm.planners.pddlstream.knowledge import Knowledge
from stalm.planners.pddlstream.pddl_text import Fact, problem_pddl
from stalm.planners.pddlstream.values import GRASP, MOTION, POSE, is_optimistic


@dataclass(frozen=True)
class AdaptiveSettings:
    initial_complexity: int = 1
    """Complexity limit of the first search (1: each stream once on the initial objects)."""
    search: str = SEARCH
    memory_limit_mb: int = 2048
    """Cap on one Fast Downward search (the machine is shared; PDDLStream runs it alike)."""


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
class StreamPlanEvaluation:
    """An evaluated stream plan: its instances, how many were evaluated before the first
    failure (``failed``, None: none failed) and the seconds its sampling, its tests and the
    whole evaluation took (to the millisecond)."""

    stream_plan: int
    evaluated: int
    failed: str | None
    sampling_s: float
    tests_s: float
    stream_plan_s: float


@dataclass(frozen=True, kw_only=True)
class IterationRecord:
    """What one adaptive iteration did, for the result: the objects of its optimistic problem,
    Fast Downward's seconds and how the iteration ended (``result``); a plan's length, the
    instances re-enabled after no plan, the stream plan's evaluation, and the step whose
    execution failed with the facts learned from it, when there were such."""

    complexity_limit: int
    real_objects: int
    optimistic_objects: int
    pddl_objects: int
    fd_translate_s: float
    fd_search_s: float
    plan_length: int | None = None
    result: str
    reenabled: int | None = None
    evaluation: StreamPlanEvaluation | None = None
    execution_failure: str | None = None
    learned: tuple[str, ...] | None = None

    def to_json(self) -> JsonObject:
        """The fields, those not known left out, and the evaluation's in its place."""
        data = record_json(self, omitted_when_none=_OMITTED_WHEN_NONE)
        return {
            key: value
            for name, field_value in data.items()
            for key, value in (
                field_value.items() if name == "evaluation" else [(name, field_value)]
            )
        }


_OMITTED_WHEN_NONE = ("plan_length", "reenabled", "evaluation", "execution_failure", "learned")


@dataclass(frozen=True)
class Iteration:
    """One adaptive iteration: what it did (``record``), and the plan when it uses real
    objects only (the caller executes it)."""

    record: IterationRecord
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
        search = fast_downward(
            text, self.settings.search, deadline - time.monotonic(), self.settings.memory_limit_mb
        )
        self.fd_seconds += search.translate_s + search.search_s
        self.translate_seconds += search.translate_s
        record = IterationRecord(
            complexity_limit=self.limit,
            real_objects=knowledge.object_count,
            optimistic_objects=len(optimistic),
            pddl_objects=knowledge.object_count + len(optimistic) + own,
            fd_translate_s=round(search.translate_s, 3),
            fd_search_s=round(search.search_s, 3),
            result=search.reason,
        )
        if search.steps is None:
            if time.monotonic() < deadline:
                record = replace(record, reenabled=self.streams.reenable())
                self.limit += 1
            return Iteration(record, None)
        record = replace(record, plan_length=len(search.steps))
        to_evaluate = stream_plan(search.steps, optimistic)
        if not to_evaluate:
            return Iteration(replace(record, result="plan over real objects"), search.steps)
        evaluation = self._evaluate(to_evaluate, rng, deadline)
        result = "stream failure" if evaluation.failed else "streams evaluated"
        return Iteration(replace(record, result=result, evaluation=evaluation), None)

    def _evaluate(
        self, to_evaluate: list[Optimistic], rng: np.random.Generator, deadline: float
    ) -> StreamPlanEvaluation:
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
        return StreamPlanEvaluation(
            stream_plan=len(to_evaluate),
            evaluated=evaluated,
            failed=failed,
            sampling_s=round(self.streams.seconds - sampling_before, 3),
            tests_s=round(self.knowledge.test_seconds - tests_before, 3),
            stream_plan_s=round(time.monotonic() - tick, 3),
        )
