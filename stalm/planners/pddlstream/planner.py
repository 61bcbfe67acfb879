"""The PDDLStream baseline (paper §4.2): the adaptive algorithm over our domain, run online.

One wall-clock deadline covers the trial. Each iteration builds the optimistic problem over
every real object computed so far plus optimistic outputs of the enabled stream instances
(:mod:`.adaptive`), searches it with Fast Downward, and either evaluates the plan's stream
plan (sampling with ψ, IK, sweeping the new motions against every known pose) or, when the
plan uses real objects only, executes it in the domain step by step (:mod:`.execute`). A step
that fails there becomes a fact and the planner re-plans from the state reached. The executed
plan is replayed in a fresh scene at the end, as for every planner; a plan that fails replay is
a failure.

``PlanResult.details`` records the method's documented weakness (paper §4.3): the number of
PDDL objects per iteration grows, and with it Fast Downward's time. Phase times map as: Fast
Downward (translate + search) → ``tree_search``, stream sampling and motion planning →
``concretize``, the collision and relation tests of new objects → ``predicates``.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from stalm.domain.mdp import Domain
from stalm.domain.outcome import Infeasibility
from stalm.domain.params import Action
from stalm.domain.samplers import SamplerSettings
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.planners.pddlstream.adaptive import Adaptive, AdaptiveSettings, IterationRecord
from stalm.planners.pddlstream.execute import build_action, learn_from
from stalm.planners.pddlstream.instances import Streams
from stalm.planners.pddlstream.knowledge import Knowledge
from stalm.planners.pddlstream.pddl_text import Fact, goal_fact
from stalm.planners.pddlstream.streams import StreamGeometry
from stalm.planners.pddlstream.values import PoseValue
from stalm.progress import Progress, observer_of
from stalm.settings.tree import RunSettings
from stalm.trial.details import DirectRecord, ReplayCheck, RunDetails
from stalm.trial.replay import replay_plan
from stalm.trial.result import (
    Counters,
    PhaseTimes,
    PlanResult,
    check_seed,
    check_time_budget,
    cpu_seconds,
)
from stalm.world.problem import Problem
from stalm.world.relations import supporting_region
from stalm.world.state import State


@dataclass(frozen=True)
class PddlStreamDetails(DirectRecord):
    """PDDLStream's record of a trial: each iteration (:class:`IterationRecord`), the real
    objects and complexity limit it ended with, what the streams and tests did, Fast
    Downward's seconds, and the plan steps whose execution failed. Seconds are to the
    millisecond."""

    iterations: tuple[IterationRecord, ...]
    final_objects: dict[str, int]
    """Real objects by PDDL type (pose, grasp, motion)."""
    final_complexity_limit: int
    stream_calls: int
    stream_failures: int
    stream_instances: int
    fd_seconds: float
    fd_translate_seconds: float
    sampling_seconds: float
    test_seconds: float
    collision_tests: int
    execution_failures: tuple[str, ...]


class PDDLStreamPlanner:
    """PDDLStream's adaptive algorithm with Fast Downward, over ψ's samplers as streams.

    ``settings`` is the run's settings tree, as every planner takes it (None: its defaults);
    of it only ψ's section (``samplers``, which the streams draw with) applies: the method uses
    no language model and no search tree. ``adaptive`` holds PDDLStream's own constants
    (:class:`AdaptiveSettings`), which the tree does not hold."""

    name = "pddlstream-adaptive"

    def __init__(
        self,
        settings: RunSettings | None = None,
        progress: Progress | None = None,
        adaptive: AdaptiveSettings | None = None,
    ) -> None:
        self.samplers: SamplerSettings = (settings or RunSettings()).samplers
        self.adaptive = adaptive or AdaptiveSettings()
        self.say = observer_of(progress).message

    def solve(self, problem: Problem, seed: int, time_budget_s: float | None = None) -> PlanResult:
        seed = check_seed(seed)
        time_budget_s = check_time_budget(time_budget_s)
        start_time = time.monotonic()
        cpu_start = cpu_seconds()
        budget = time_budget_s if time_budget_s is not None else problem.spec.time_budget_s
        domain = Domain.create(problem, sampler_settings=self.samplers)
        try:
            result = self._run(domain, problem, seed, start_time, start_time + budget)
        finally:
            domain.close()
        cpu = cpu_seconds() - cpu_start
        return dataclasses.replace(result, times=dataclasses.replace(result.times, cpu=cpu))

    def _run(
        self, domain: Domain, problem: Problem, seed: int, start_time: float, deadline: float
    ) -> PlanResult:
        rng = np.random.default_rng(seed)
        state = problem.initial_state
        adaptive = adaptive_for(domain, problem, self.adaptive)
        setup_s = time.monotonic() - start_time  # the scene, the domain and the algorithm's state
        knowledge = adaptive.knowledge
        streams = adaptive.streams
        execution_s = 0.0
        executed: list[Action] = []
        states: list[State] = [state]
        held_grasp: str | None = None
        iterations: list[IterationRecord] = []
        execution_failures: list[str] = []
        termination = "timeout"
        while True:
            if domain.is_goal(state):
                termination = "goal"
                break
            if len(executed) >= problem.horizon:
                termination = "horizon"
                break
            if time.monotonic() >= deadline:
                break
            self.say(
                f"iteration {len(iterations)}: {knowledge.object_count} real objects, "
                f"complexity limit {adaptive.limit}"
            )
            iteration = adaptive.iterate(fluents(knowledge, state, held_grasp), rng, deadline)
            iterations.append(iteration.record)
            if iteration.plan is None:
                continue
            tick = time.monotonic()
            for step in iteration.plan:
                if len(executed) >= problem.horizon:
                    break
                built = build_action(domain, knowledge, state, step)
                if isinstance(built, Infeasibility):
                    failure = learn_from(knowledge, state, step, built)
                    execution_failures.append(f"{' '.join(step)}: {built}")
                    iterations[-1] = dataclasses.replace(
                        iteration.record,
                        execution_failure=str(built),
                        learned=tuple(" ".join(f) for f in failure.learned),
                    )
                    break
                state = domain.step(state, built).state
                executed.append(built)
                states.append(state)
                if step[0] == "pick":
                    held_grasp = step[3]
                elif step[0] == "place":
                    held_grasp = None
                self.say(f"executed {built.discrete}")
            execution_s += time.monotonic() - tick

        replay_reason = None
        if termination == "goal":
            tick = time.monotonic()
            report = replay_plan(problem, problem.initial_state, executed)
            execution_s += time.monotonic() - tick
            replay_reason = report.reason
            if not report.reached_goal:
                termination = "replay_failed"
        total = time.monotonic() - start_time
        return PlanResult(
            problem=problem.name,
            planner=self.name,
            seed=seed,
            success=termination == "goal",
            plan=tuple(executed),
            states=tuple(states),
            times=PhaseTimes(
                predicates=knowledge.test_seconds,
                concretize=streams.seconds,
                tree_search=adaptive.fd_seconds,
                execution=execution_s,
                total=total,
                setup=setup_s,
            ),
            counters=Counters(
                transitions=domain.counters.transitions,
                samples=streams.calls,
                collision_checks=domain.sim.collision_checks,
                replans=len(iterations),
            ),
            termination=termination,
            details=RunDetails(
                PddlStreamDetails(
                    iterations=tuple(iterations),
                    final_objects=knowledge.counts(),
                    final_complexity_limit=adaptive.limit,
                    stream_calls=streams.calls,
                    stream_failures=streams.failures,
                    stream_instances=len(streams.records),
                    fd_seconds=round(adaptive.fd_seconds, 3),
                    fd_translate_seconds=round(adaptive.translate_seconds, 3),
                    sampling_seconds=round(streams.seconds, 3),
                    test_seconds=round(knowledge.test_seconds, 3),
                    collision_tests=knowledge.geometry.collision_tests,
                    execution_failures=tuple(execution_failures),
                ),
                ReplayCheck(replay_reason),
            ),
        )


def adaptive_for(domain: Domain, problem: Problem, settings: AdaptiveSettings) -> Adaptive:
    """The adaptive loop at the start of a trial: the initial poses are its only objects."""
    state = problem.initial_state
    if state.held is not None:
        raise StalmError("pddlstream-adaptive needs a problem that starts with an empty hand")
    knowledge = Knowledge(StreamGeometry(domain))
    for obj, pose in state.poses:
        region = supporting_region(problem.spec, pose)
        if region is None:
            raise StalmError(f"'{obj}' rests on no region in the initial state")
        knowledge.add_pose(PoseValue(obj, pose, region))
    vocabulary = Vocabulary.from_problem(problem)
    return Adaptive(
        Streams(knowledge, vocabulary.movables, vocabulary.regions, vocabulary.doors),
        {"movable": vocabulary.movables, "region": vocabulary.regions, "door": vocabulary.doors},
        tuple(goal_fact(g.obj, g.direction, g.ref) for g in problem.goal),
        settings,
    )


def fluents(knowledge: Knowledge, state: State, held_grasp: str | None) -> list[Fact]:
    """The current state as fluent facts over the real pose and grasp objects."""
    facts: list[Fact] = []
    for obj, pose in state.poses:
        name = knowledge.pose_name(obj, pose)
        if name is None:
            raise StalmError(f"'{obj}' rests at a pose no stream produced")
        facts.append(("AtPose", obj, name))
    if state.held is None:
        facts.append(("HandEmpty",))
    else:
        if held_grasp is None:
            raise StalmError(f"'{state.held.obj}' is held by a grasp no stream produced")
        facts.append(("Holding", state.held.obj, held_grasp))
    for door in knowledge.geometry.spec.doors:
        if not state.is_open(door.name):
            facts.append(("IsClosed", door.name))
    return facts
