"""PDDLStream's adaptive baseline: its PDDL, its streams, the adaptive loop and a P2 solve."""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest

from stalm.domain.mdp import Domain
from stalm.domain.outcome import Infeasibility
from stalm.planners.pddlstream import PDDLStreamPlanner
from stalm.planners.pddlstream.adaptive import Adaptive, AdaptiveSettings, optimistic_problem
from stalm.planners.pddlstream.downward import SEARCH, fast_downward
from stalm.planners.pddlstream.execute import learn_from
from stalm.planners.pddlstream.instances import StreamKey
from stalm.planners.pddlstream.pddl_text import DOMAIN_PDDL
from stalm.planners.pddlstream.planner import adaptive_for, fluents
from stalm.planners.pddlstream.values import PoseValue, is_optimistic
from stalm.planners.registry import build_planner
from stalm.proposers.fast_downward import translate_task
from stalm.trial.replay import replay_plan
from stalm.world.problem import Problem
from stalm.world.state import ObjectPose
from tests.flat_settings import settings_of


@pytest.fixture(scope="module")
def p2_domain(problems: dict[str, Problem]) -> Iterator[Domain]:
    """A P2 domain of this module's own: the streams reconfigure its simulator freely."""
    domain = Domain.create(problems["P2"])
    yield domain
    domain.close()


def _adaptive(domain: Domain) -> Adaptive:
    return adaptive_for(domain, domain.problem, AdaptiveSettings())


def _initial_fluents(adaptive: Adaptive) -> list[tuple[str, ...]]:
    return fluents(adaptive.knowledge, adaptive.knowledge.geometry.problem.initial_state, None)


def test_the_optimistic_pddl_is_accepted_by_the_translator_and_solved(p2_domain, tmp_path) -> None:
    adaptive = _adaptive(p2_domain)
    optimistic = adaptive.streams.instantiate(adaptive.limit)
    text = optimistic_problem(
        adaptive.knowledge, optimistic, adaptive.names, _initial_fluents(adaptive), adaptive.goal
    )
    (tmp_path / "domain.pddl").write_text(DOMAIN_PDDL)
    (tmp_path / "problem.pddl").write_text(text)
    translate_task(tmp_path, 60.0)
    sas = (tmp_path / "task.sas").read_text()
    # ground operators over the initial poses and optimistic grasps/motions, and the derived
    # predicates (UnsafeMotion, OnRegion, RelTo) compiled into axioms
    assert "begin_operator\npick salter pose_" in sas
    assert "opt_motion_" in sas and "begin_rule" in sas
    search = fast_downward(text, SEARCH, 60.0)
    assert search.steps is not None
    # with nothing evaluated yet the plan must rest on optimistic objects, and it ends by
    # placing the salter at an optimistic pose certified right of bottle1 on table2
    assert any(is_optimistic(arg) for step in search.steps for arg in step[1:])
    assert search.steps[-1][:2] == ("place", "salter")
    final_pose = optimistic[search.steps[-1][2]]
    assert final_pose.key.stream == "sample-rel-pose"
    assert final_pose.key.inputs[:3] == ("salter", "right_of", "bottle1")


def test_pddl_objects_accumulate_across_adaptive_iterations(p2_domain) -> None:
    adaptive = _adaptive(p2_domain)
    knowledge = adaptive.knowledge
    rng = np.random.default_rng(0)
    before = knowledge.object_count
    assert before == 4  # the initial poses of P2's four objects
    counts = [before]
    records = []
    for _ in range(4):
        iteration = adaptive.iterate(_initial_fluents(adaptive), rng, time.monotonic() + 60.0)
        records.append(iteration.record)
        counts.append(knowledge.object_count)
        evaluation = iteration.record.evaluation
        if evaluation is not None and evaluation.failed:
            # the failed instance is disabled: the next optimistic problem does not offer it
            offered = {str(o.key) for o in adaptive.streams.instantiate(adaptive.limit).values()}
            assert evaluation.failed not in offered
    assert counts == sorted(counts) and counts[-1] > before
    assert records[-1].pddl_objects > records[0].pddl_objects
    # nothing is ever dropped: every real object is still an object of the next problem
    text = optimistic_problem(
        knowledge,
        adaptive.streams.instantiate(adaptive.limit),
        adaptive.names,
        _initial_fluents(adaptive),
        adaptive.goal,
    )
    objects = text.split("(:init")[0]
    for name in [*knowledge.poses, *knowledge.grasps, *knowledge.motions]:
        assert f" {name} " in objects or f" {name}\n" in objects


def test_a_failed_stream_instance_is_not_retried_immediately(p2_domain) -> None:
    adaptive = _adaptive(p2_domain)
    streams, knowledge = adaptive.streams, adaptive.knowledge
    rng = np.random.default_rng(3)
    # a pose on table2, in the hall, claimed to be reached from counter2's standing pose in
    # the kitchen: no IK solution exists, so placing there fails
    far = knowledge.add_pose(PoseValue("salter", ObjectPose.make(3.0, 2.2, 1.0, 0.0), "counter2"))
    grasp = knowledge.add_grasp(knowledge.geometry.sample_grasp("salter", rng))
    key = StreamKey("plan-place", ("salter", far, grasp))
    assert key in {o.key for o in streams.instantiate(1).values()}
    outcome = streams.evaluate(key, rng)
    assert outcome.produced is None and streams.records[key].disabled
    # disabled: not offered at this limit nor at any higher one, until a search fails
    for limit in (1, 2, 5):
        assert key not in {o.key for o in streams.instantiate(limit).values()}
    assert streams.reenable() == 1
    # re-enabled, the failed call counts toward its complexity: only offered at limit >= 1
    assert key not in {o.key for o in streams.instantiate(0).values()}
    offered = {o.key: o for o in streams.instantiate(1).values()}
    assert offered[key].complexity == 2


def test_an_execution_failure_becomes_a_fact_or_retires_the_motion(p2_domain) -> None:
    adaptive = _adaptive(p2_domain)
    knowledge = adaptive.knowledge
    state = p2_domain.problem.initial_state
    outcome = adaptive.streams.evaluate(
        StreamKey("plan-open", ("kitchen_door",)), np.random.default_rng(0)
    )
    assert outcome.produced is not None
    step = ("open", "kitchen_door", outcome.produced)
    blocked = Infeasibility("base_path_blocked", "test", ("bottle1",))
    learned = learn_from(knowledge, state, step, blocked)
    bottle1_pose = knowledge.pose_name("bottle1", state.pose("bottle1"))
    assert learned.learned == (("Collides", outcome.produced, "bottle1", bottle1_pose),)
    assert not learned.retired and learned.learned[0] in knowledge.facts
    unexplained = learn_from(knowledge, state, step, Infeasibility("no_ik", "test"))
    assert unexplained.retired and outcome.produced not in knowledge.usable_motions()
    assert ("OpenKin", "kitchen_door", outcome.produced) not in knowledge.facts


def test_the_registry_builds_it() -> None:
    planner = build_planner("pddlstream-adaptive", settings_of())
    assert isinstance(planner, PDDLStreamPlanner) and planner.name == "pddlstream-adaptive"


@pytest.mark.slow
def test_pddlstream_adaptive_solves_p2(problems) -> None:
    problem = problems["P2"]
    result = PDDLStreamPlanner().solve(problem, seed=0, time_budget_s=300.0)
    data = result.to_json()
    assert data["success"] is True and data["termination"] == "goal"
    assert data["planner"] == "pddlstream-adaptive" and data["counters"]["llm_calls"] == 0
    real = [record["real_objects"] for record in data["details"]["iterations"]]
    assert real == sorted(real) and real[-1] > real[0]
    assert replay_plan(problem, problem.initial_state, list(result.plan)).reached_goal
