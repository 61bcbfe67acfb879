"""The online-planner base: nested phase timing, the one predicate memo, the planners' names,
and the registry above the planners."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import pytest

from stalm.domain.actions import Open, Pick
from stalm.planners.llm_mcts import LlmMctsPlanner
from stalm.planners.registry import build_planner, planners
from stalm.planners.stalm import (
    StalmSteps,
    best_prefix_first_action,
    warm_started_search,
)
from stalm.planners.uct import UctSteps
from stalm.predicates.engine import PredicateCache
from stalm.predicates.memo import PredicateMemo
from stalm.predicates.samples import MotionSamples
from stalm.trial.episode import PhaseClock
from stalm.trial.online import OnlinePlanner
from tests.flat_settings import settings_of

PLANNERS = Path(__file__).resolve().parents[2] / "stalm" / "planners"


def test_a_phase_timed_inside_another_is_not_charged_to_the_outer_one() -> None:
    clock = PhaseClock()
    with clock.timed("tree"):
        time.sleep(0.02)
        with clock.timed("predicates"):
            time.sleep(0.05)
        with clock.timed(None):  # a query: its seconds are charged elsewhere
            time.sleep(0.05)
    assert clock.predicates >= 0.05
    assert 0.02 <= clock.tree < 0.05, "the tree phase excludes the nested blocks"


class EngineDouble:
    """A predicate-engine double: records which states were computed and brought forward."""

    problem = None

    def __init__(self) -> None:
        self.computed: list[object] = []
        self.updated: list[tuple[object, object, object]] = []

    def compute(
        self, state: object, deadline: object = None, report: object = None
    ) -> PredicateCache:
        self.computed.append(state)
        return PredicateCache(state=state, literals=frozenset())  # type: ignore[arg-type]

    def update(
        self,
        cache: PredicateCache,
        action: object,
        state: object,
        deadline: object = None,
        report: object = None,
    ) -> PredicateCache:
        self.updated.append((cache.state, action, state))
        return PredicateCache(state=state, literals=frozenset())  # type: ignore[arg-type]


def test_the_memo_computes_a_state_once_and_brings_the_rest_forward_along_a_path() -> None:
    engine = EngineDouble()
    memo = PredicateMemo(engine)  # type: ignore[arg-type]
    first = memo.of("s0")  # type: ignore[arg-type]
    assert memo.of("s0") is first and engine.computed == ["s0"]  # type: ignore[arg-type]
    # an executed path s0 -open-> s1 -pick-> s2: each state from its parent's
    opened, picked = _action(Open("kitchen_door")), _action(Pick("salter"))
    memo.along(["s0", "s1", "s2"], [opened, picked])  # type: ignore[list-item]
    assert engine.updated == [
        ("s0", Open("kitchen_door"), "s1"),
        ("s1", Pick("salter"), "s2"),
    ]
    # a leaf whose parent is known (as a search's arrival edge gives it) is not recomputed
    memo.of("s3", "s1", Pick("bottle1"))  # type: ignore[arg-type]
    assert (memo.computed_from_scratch, memo.brought_forward) == (1, 3)
    assert memo.known("s3") is not None and memo.known("s9") is None  # type: ignore[arg-type]


def _action(discrete: object) -> object:
    class ActionDouble:
        def __init__(self) -> None:
            self.discrete = discrete

    return ActionDouble()


@pytest.mark.parametrize(
    "name",
    ["stalm", "stalm-no-uct", "uct", "uct-hcount", "ep-saycan", "iterative-replanning", "llm-mcts"],
)
def test_each_online_row_is_the_one_loop_around_its_method_named_by_the_paper(name) -> None:
    planner = build_planner(name, settings_of(llm="http://127.0.0.1:9/v1#m"))
    assert type(planner) is OnlinePlanner and planner.name == name
    assert name in planners()


def test_the_ablations_differ_from_their_planner_only_in_their_steps_part() -> None:
    """STaLM w/o UCT is STaLM's step with another no-goal-plan part; UCT-with-Hcount is
    UCT's step with Hcount as the leaf value (and the occlusion predicates it reads)."""
    settings = settings_of(proposer="symbolic")
    stalm, ablation = build_planner("stalm", settings), build_planner("stalm-no-uct", settings)
    assert isinstance(stalm.start, StalmSteps) and isinstance(ablation.start, StalmSteps)
    assert stalm.start.no_goal_plan is warm_started_search
    assert ablation.start.no_goal_plan is best_prefix_first_action
    assert replace(ablation.start, no_goal_plan=warm_started_search) == stalm.start
    uct, hcount = build_planner("uct", settings), build_planner("uct-hcount", settings)
    assert isinstance(uct.start, UctSteps) and isinstance(hcount.start, UctSteps)
    assert (uct.start.hcount, hcount.start.hcount) == (False, True)
    assert uct.start.settings == hcount.start.settings
    assert uct.settings == hcount.settings


@pytest.mark.parametrize("planner", ["stalm", "uct-hcount"])
def test_a_trial_ends_at_its_deadline_while_predicates_are_computed(
    problems, domain_factory, monkeypatch, planner
) -> None:
    """A one-second trial whose first predicates take longer (each pick record slowed to
    0.4 s here, so P2's four objects need 1.6 s whatever the machine) stops inside them
    (STaLM's prompt predicates; UCT-with-Hcount's, from a leaf inside its search) as a
    'timeout' with its result. The base roadmaps are built first (a trial reads them from the
    disk cache): building one is the problem's cost, once per machine, and no deadline bounds
    it."""
    pick_record = MotionSamples.pick_record

    def slow_pick_record(self: MotionSamples, *args: object, **kwargs: object) -> object:
        time.sleep(0.4)
        return pick_record(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(MotionSamples, "pick_record", slow_pick_record)
    p2 = domain_factory("P2")
    doors = frozenset(door.name for door in p2.problem.spec.doors)
    for open_doors in (frozenset(), doors):
        p2.base_planner.roadmap(open_doors)
    budget = 1.0
    config = settings_of(proposer="symbolic")
    result = build_planner(planner, config).solve(problems["P2"], seed=0, time_budget_s=budget)
    assert result.termination == "timeout" and not result.success
    assert result.times.total <= budget + 1.5, result.times  # less than the slowed predicates take
    assert result.times.predicates <= result.times.total
    assert result.plan == () and result.states == (problems["P2"].initial_state,)
    assert result.counters.collision_checks > 0  # the predicates were being computed


def test_llm_mcts_keeps_the_executed_childs_subtree_and_priors_when_asked_to(problems) -> None:
    from stalm.domain.actions import Place
    from stalm.llm.prompt import PromptOptions
    from stalm.proposers.language_model import LLMProposer
    from stalm.settings.io import with_values
    from stalm.settings.tree import RunSettings
    from stalm.world.problem import Problem
    from tests.planners.llm_reply_doubles import ScriptedReplyBackendDouble, plan_reply

    p2 = problems["P2"]
    short = Problem(p2.spec.model_copy(update={"horizon": 2}), p2.source)
    reply = plan_reply([Open("kitchen_door"), Pick("bottle2"), Place("bottle2", "on", "counter1")])

    def run(reuse: bool) -> dict[str, object]:
        backend = ScriptedReplyBackendDouble(queue=[[reply]])
        no_occlusion = PromptOptions(occlusion_predicates=False)
        settings = with_values(
            RunSettings(),
            [
                ("search.sims", 3),
                ("search.horizon", 2),
                ("search.batch", 2),
                ("prompt.occlusion_predicates", False),
                ("execution.reuse_tree", reuse),
            ],
            "test settings",
        )
        planner = LlmMctsPlanner(LLMProposer(backend, no_occlusion), settings)
        result = planner.solve(short, 0, 600.0)
        assert len(result.plan) == 2
        return result.details.to_json()

    kept = run(True)
    reused = kept["reused_root_visits"]
    assert isinstance(reused, list) and reused and all(v > 0 for v in reused)
    # the second step's root and the nodes under it already have their priors: fewer calls
    fresh = run(False)
    assert "reused_root_visits" not in fresh
    calls_kept, calls_fresh = kept["llm_calls_per_step"], fresh["llm_calls_per_step"]
    assert isinstance(calls_kept, list) and isinstance(calls_fresh, list)
    assert calls_kept[0] == calls_fresh[0] and calls_kept[1] < calls_fresh[1]


PLANNER_MODULES = (
    "stalm.planners.stalm",
    "stalm.planners.uct",
    "stalm.planners.saycan",
    "stalm.planners.iterative_replanning",
    "stalm.planners.llm_mcts",
    "stalm.planners.pddlstream",
    "stalm.proposers.fast_downward",
)


def _loaded_after(code: str) -> set[str]:
    """The stalm modules a fresh interpreter has loaded after running ``code``."""
    import json
    import os
    import subprocess
    import sys

    root = str(PLANNERS.parents[1])
    env = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    script = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=env,
        cwd=root,  # python -c puts the working folder first on the path
        check=True,
    )
    return {m for m in json.loads(done.stdout.splitlines()[-1]) if m.startswith("stalm")}


def test_the_registry_imports_a_planner_only_to_build_it() -> None:
    listed = _loaded_after(
        "from stalm.planners.registry import planners, resolve, RunSettings\n"
        "assert len(planners()) == 8\nresolve('uct', RunSettings())"
    )
    assert listed.isdisjoint(PLANNER_MODULES), sorted(listed & set(PLANNER_MODULES))
    built = _loaded_after("from stalm.planners.registry import build_planner\nbuild_planner('uct')")
    assert "stalm.planners.uct" in built and "stalm.planners.llm_mcts" not in built


def test_stalm_help_loads_no_planner() -> None:
    loaded = _loaded_after(
        "import sys\nsys.argv = ['stalm', '--help']\nfrom stalm.cli.main import main\n"
        "try:\n    main()\nexcept SystemExit:\n    pass"
    )
    assert "stalm.cli.main" in loaded
    assert loaded.isdisjoint({*PLANNER_MODULES, "stalm.planners.registry"}), sorted(loaded)
