"""LLM-MCTS: the LLM prior (votes, one query per node of a tree, seeds, deadline), PUCT with it
inside the search (asked at every new node, followed from the first selection), and the planner
end to end on the smallest case with a scripted backend in place of the model."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from stalm.domain.actions import Open, Pick, Place
from stalm.llm.backends.base import LLMRequest, LLMResponse
from stalm.llm.cache import CachedBackend
from stalm.llm.cache_file import ReplyCache
from stalm.llm.prompt import PromptOptions
from stalm.planners.llm_mcts import (
    LlmMcts,
    LlmMctsPlanner,
    LLMPrior,
    llm_mcts_policies,
)
from stalm.planners.registry import build_planner
from stalm.proposers.language_model import LLMProposer
from stalm.proposers.protocol import Proposal, ProposalRequest
from stalm.search import SearchSettings, SearchTree, warm_started_uct
from stalm.search.puct import AUTHORS_UNIFORM_WEIGHT, uniform_prior
from stalm.settings.io import with_overrides
from stalm.settings.tree import RunSettings
from stalm.trial.query_seeds import state_request_seed
from stalm.trial.replay import replay_result_json
from stalm.world.problem import load_problem
from stalm.world.state import ObjectPose
from tests.flat_settings import settings_of
from tests.planners.mcts_doubles import (
    PlanFollowingBackendDouble,
    ScriptedRepliesBackendDouble,
    SymbolicLiteralsDouble,
    plan_text,
)
from tests.planners.test_stalm import P2_PLAN

MIXED_REPLIES = (
    plan_text([Pick("bottle2"), Place("bottle2", "on", "counter1")]),
    plan_text([Pick("bottle2")]),
    plan_text([Pick("salter")]),
    "I am sorry, I cannot produce a plan.",
    plan_text([Place("bottle3", "on", "counter1")]),  # hand empty: not legal
)


def _prior(problem, backend, literals=None, seed: int = 0, deadline=None) -> LLMPrior:
    return LLMPrior(
        problem,
        LLMProposer(backend),
        literals or SymbolicLiteralsDouble(),
        trial_seed=seed,
        samples=5,
        deadline=deadline,
    )


class TrialClockDouble:
    """Test double of the episode's clock: a deadline that charging a query moves earlier."""

    def __init__(self, deadline: float) -> None:
        self.deadline = deadline

    def read(self) -> float:
        return self.deadline

    def record_query(self, proposal: Proposal) -> None:
        self.deadline -= proposal.original_seconds - proposal.seconds


def _moved(state, name: str, dx: float):
    pose = state.pose(name)
    return state.with_changes(poses={name: ObjectPose.make(pose.x + dx, pose.y, pose.z, pose.yaw)})


def test_prior_counts_first_actions_over_five_replies_and_mixes_with_uniform(
    problems, domain_factory
) -> None:
    problem = problems["P2"]
    state = problem.initial_state
    legal = domain_factory("P2").legal_actions(state)
    backend = ScriptedRepliesBackendDouble(MIXED_REPLIES)
    prior = _prior(problem, backend, seed=3)
    probabilities = prior(state, legal)
    by_action = dict(zip(legal, probabilities, strict=True))
    # 5 legal actions (4 picks, the door). Votes/5: bottle2 0.4, salter 0.2; mixed 0.5 with
    # uniform 0.2 each: 0.3, 0.2, the other three 0.1; sum 0.8, renormalised: / 0.8
    assert len(legal) == 5
    assert by_action[Pick("bottle2")] == pytest.approx(0.375)
    assert by_action[Pick("salter")] == pytest.approx(0.25)
    others = [p for a, p in by_action.items() if a not in (Pick("bottle2"), Pick("salter"))]
    assert others == pytest.approx([0.125] * 3)
    assert probabilities.sum() == pytest.approx(1.0)
    request = backend.requests[0]
    assert request.n == 5 and request.temperature == 1.0
    assert request.seed == state_request_seed(3, state)
    stats = prior.stats
    assert (stats.states, stats.llm_calls, stats.votes, stats.unusable_replies) == (1, 1, 3, 2)
    assert stats.prompt_tokens == 100 and stats.completion_tokens == 100


def test_prior_asks_once_per_distinct_state_of_a_tree_and_again_in_a_new_tree(
    problems, domain_factory
) -> None:
    problem = problems["P2"]
    first = problem.initial_state
    second = _moved(first, "bottle1", 0.01)
    legal = domain_factory("P2").legal_actions(first)
    backend = ScriptedRepliesBackendDouble(MIXED_REPLIES)
    literals = SymbolicLiteralsDouble()
    prior = _prior(problem, backend, literals)
    a = prior(first, legal)
    assert np.array_equal(prior(first, legal), a)
    assert len(backend.requests) == 1 and literals.states == [first]
    prior(second, legal)
    prior.prepare(second, legal)
    assert len(backend.requests) == 2 and literals.states == [first, second]
    seeds = [request.seed for request in backend.requests]
    assert seeds == [state_request_seed(0, first), state_request_seed(0, second)]
    assert seeds[0] != seeds[1]
    assert prior.stats.states == 2 and prior.stats.llm_calls == 2
    # the next real step builds a new tree: its nodes are new nodes, each a new call
    prior.new_tree()
    assert np.array_equal(prior(first, legal), a)
    assert len(backend.requests) == 3 and prior.stats.llm_calls == 3


def test_request_seeds_are_stable_and_depend_on_trial_and_state(problems) -> None:
    state = problems["P2"].initial_state
    seed = state_request_seed(0, state)
    assert seed == state_request_seed(0, _moved(_moved(state, "salter", 0.02), "salter", -0.02))
    assert seed != state_request_seed(1, state)
    assert seed != state_request_seed(0, _moved(state, "salter", 0.02))
    assert 0 <= seed < 2**31


def test_after_the_deadline_the_prior_is_uniform_without_asking(problems, domain_factory) -> None:
    problem = problems["P2"]
    state = problem.initial_state
    legal = domain_factory("P2").legal_actions(state)
    backend = ScriptedRepliesBackendDouble(MIXED_REPLIES)
    clock = TrialClockDouble(time.monotonic() - 1.0)
    prior = _prior(problem, backend, deadline=clock.read)
    assert prior(state, legal) == pytest.approx([0.2] * 5)
    assert backend.requests == [] and prior.stats.deadline_fallbacks == 1
    clock.deadline = time.monotonic() + 100.0  # the uniform fallback was not memoised: it asks
    assert prior(state, legal)[legal.index(Pick("bottle2"))] == pytest.approx(0.375)
    assert len(backend.requests) == 1


def _search(domain, problem, prior: LLMPrior, budget: int, seed: int = 0, tree=None):
    """LLM-MCTS's search from P2's initial state, horizon 3 (rollouts stay short): the tree
    and the search result."""
    root = problem.initial_state
    tree = tree or SearchTree.for_root(domain, root)
    settings = SearchSettings(budget=budget, horizon=3)
    rng = np.random.default_rng(seed)
    policies = llm_mcts_policies(settings, prior)
    result = warm_started_uct(
        domain, root, (), rng, settings=settings, policies=policies, tree=tree
    )
    return tree, result


def _prior_following_p2_plan(problem):
    backend = PlanFollowingBackendDouble(P2_PLAN)
    return backend, _prior(problem, backend, SymbolicLiteralsDouble(["kitchen_door"]))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_first_simulation_follows_the_prior_and_its_new_node_is_asked_at_once(
    problems, domain_factory, seed: int
) -> None:
    problem = problems["P2"]
    domain = domain_factory("P2")
    backend, prior = _prior_following_p2_plan(problem)
    tree, result = _search(domain, problem, prior, budget=1, seed=seed)
    assert result.counters.simulations == 1
    visited = {str(c.action): c.n for c in tree.node(problem.initial_state).children if c.n}
    # every reply starts with open(kitchen_door): 0.5 + 0.5/5 = 0.6 against 0.1 for the other
    # four root actions, so the very first selection opens the door (whatever the seed)
    assert visited == {str(Open("kitchen_door")): 1}
    # one call per node: the root when selected from, the door-open state (if ψ found a way
    # to open it; one try only) when the simulation created its node
    [kappa] = tree.node(problem.initial_state).child(Open("kitchen_door")).children
    assert len(tree) == (2 if kappa.outcome.feasible else 1)
    assert len(backend.requests) == len(tree) == prior.stats.states
    assert {r.seed for r in backend.requests} == {state_request_seed(0, s) for s in tree.states()}


def test_search_asks_the_model_once_per_new_node_and_more_as_it_grows(
    problems, domain_factory
) -> None:
    problem = problems["P2"]
    domain = domain_factory("P2")
    backend, prior = _prior_following_p2_plan(problem)
    tree, _ = _search(domain, problem, prior, budget=4)
    assert len(backend.requests) == len(tree) == prior.stats.states >= 2
    assert {r.seed for r in backend.requests} == {state_request_seed(0, s) for s in tree.states()}
    calls_before = len(backend.requests)
    nodes_before = len(tree)
    # search on in the same tree with the same prior: new nodes, new calls, none repeated
    tree, _ = _search(domain, problem, prior, budget=4, seed=1, tree=tree)
    assert len(tree) > nodes_before
    assert len(backend.requests) == len(tree) > calls_before
    assert len({r.seed for r in backend.requests}) == len(backend.requests)


class ReplayOnlyBackendDouble(ScriptedRepliesBackendDouble):
    """Must never be reached: every request has to come from the reply cache."""

    def complete(self, request: LLMRequest) -> LLMResponse:
        raise AssertionError(f"the cache should have answered seed {request.seed}")


def test_same_seed_and_replies_give_the_same_search_also_replayed_from_the_cache(
    problems, domain_factory, tmp_path
) -> None:
    problem = problems["P2"]
    domain = domain_factory("P2")
    cache = ReplyCache(tmp_path / "replies.sqlite")
    first_backend = PlanFollowingBackendDouble(P2_PLAN)
    first_prior = _prior(
        problem,
        CachedBackend(first_backend, cache, mode="use"),
        SymbolicLiteralsDouble(["kitchen_door"]),
        seed=5,
    )
    first, first_result = _search(domain, problem, first_prior, budget=6, seed=5)
    replay = CachedBackend(ReplayOnlyBackendDouble(MIXED_REPLIES), cache, mode="replay")
    prior = _prior(problem, replay, SymbolicLiteralsDouble(["kitchen_door"]), seed=5)
    second, second_result = _search(domain, problem, prior, budget=6, seed=5)
    assert len(first_backend.requests) >= 2, "several states got a model prior"
    assert first.snapshot(str) == second.snapshot(str)
    assert first_result.best_action == second_result.best_action
    assert prior.stats.cached_calls == prior.stats.llm_calls == len(first_backend.requests)


def test_registry_builds_llm_mcts_with_the_paper_defaults() -> None:
    planner = build_planner("llm-mcts", settings_of(llm="http://127.0.0.1:9/v1#m"))
    method = planner.start
    assert isinstance(method, LlmMcts) and planner.name == "llm-mcts"
    search = method.settings.search.search_settings()
    assert search.budget == 35 and search.c == 50.0 and method.settings.search.batch == 5
    assert AUTHORS_UNIFORM_WEIGHT == 0.5
    custom = build_planner("llm-mcts", settings_of(llm="http://127.0.0.1:9/v1#m", sims=7, batch=3))
    assert isinstance(custom.start, LlmMcts)
    assert custom.start.settings.search.search_settings().budget == 7
    assert custom.start.settings.search.batch == 3
    assert planner.occlusion
    no_occlusion = settings_of(llm="http://127.0.0.1:9/v1#m", prompt__occlusion_predicates=False)
    assert not build_planner("llm-mcts", no_occlusion).occlusion


def test_llm_mcts_reuses_the_tree_by_the_one_setting_of_every_tree_planner() -> None:
    """Tree reuse (issue 13) is on for LLM-MCTS as for STaLM and UCT, and the same setting
    (execution.reuse_tree, --set reuse_tree=false) switches it off for all of them."""
    model = settings_of(llm="http://127.0.0.1:9/v1#m")
    for name in ("llm-mcts", "stalm", "uct", "uct-hcount"):
        assert build_planner(name, model).settings.execution.reuse_tree, name
        off = settings_of(llm="http://127.0.0.1:9/v1#m", reuse_tree=False)
        assert not build_planner(name, off).settings.execution.reuse_tree, name


def test_the_reused_subtree_keeps_the_n_and_q_it_had_before_the_step(problems, monkeypatch) -> None:
    """After a real step, every node of LLM-MCTS's kept subtree has the visits and values it
    had in the tree that chose the step, and the next search starts from that subtree."""
    from stalm.trial import online
    from stalm.world.problem import Problem
    from tests.planners.llm_reply_doubles import ScriptedReplyBackendDouble, plan_reply

    kept: list[tuple[dict, dict, int]] = []
    execute = online.Trial.execute

    def execute_and_compare(trial: online.Trial, action) -> None:
        tree = trial.tree
        before = {s: tree.node(s) for s in tree.states()} if tree is not None else {}
        execute(trial, action)
        if trial.tree is not None:
            after = {s: trial.tree.node(s) for s in trial.tree.states()}
            kept.append((before, after, trial.tree.visits(trial.tree.root)))

    monkeypatch.setattr(online.Trial, "execute", execute_and_compare)
    p2 = problems["P2"]
    short = Problem(p2.spec.model_copy(update={"horizon": 2}), p2.source)
    reply = plan_reply([Open("kitchen_door"), Pick("bottle2"), Place("bottle2", "on", "counter1")])
    backend = ScriptedReplyBackendDouble(queue=[[reply]])
    small = ["search.sims=3", "search.horizon=2", "search.batch=2"]
    settings = with_overrides(RunSettings(), [*small, "prompt.occlusion_predicates=false"])
    planner = LlmMctsPlanner(
        LLMProposer(backend, PromptOptions(occlusion_predicates=False)), settings
    )
    result = planner.solve(short, 0, 600.0)
    assert len(result.plan) == 2 and kept, "the first step's child subtree was kept"
    for before, after, root_visits in kept:
        assert after and root_visits > 0
        for state, node in after.items():
            assert node == before[state], "N and Q of a kept node are what they were"
    assert result.details.method.reused_root_visits == tuple(visits for _, _, visits in kept)


class CachedProposerDouble:
    """Test double: every query 'comes from the reply cache', originally 5 s, now 0 s."""

    name = "cached-double"
    takes_feedback = False

    def propose(self, request: ProposalRequest) -> Proposal:
        return Proposal((), calls=1, seconds=0.0, from_cache=True, cached_seconds=5.0)


def test_a_query_from_the_cache_is_charged_its_original_seconds_and_the_prior_sees_it(
    problems, domain_factory
) -> None:
    """The trial charges a cached query's original 5 s (its deadline, 3 s away, passes); the
    prior reads the trial's deadline, so the next new node is uniform without asking."""
    problem = problems["P2"]
    state = problem.initial_state
    legal = domain_factory("P2").legal_actions(state)
    clock = TrialClockDouble(time.monotonic() + 3.0)
    prior = LLMPrior(
        problem,
        CachedProposerDouble(),
        SymbolicLiteralsDouble(),
        trial_seed=0,
        samples=5,
        deadline=clock.read,
        on_query=clock.record_query,
    )
    prior.prepare(state, legal)
    assert prior.stats.cached_calls == prior.stats.llm_calls == 1
    assert clock.deadline < time.monotonic()
    other = _moved(state, "salter", 0.02)
    assert prior(other, legal) == pytest.approx(uniform_prior(legal))
    assert prior.stats.llm_calls == 1 and prior.stats.deadline_fallbacks == 1


def _smallest_case(tmp_path: Path):
    """P2's scene with the smallest goal: bottle1 (on table2, in the robot's room) on table1,
    two actions; horizon 4 keeps rollouts short. Every root action but one is a distraction:
    picking salter, bottle2 or bottle3, or opening the door."""
    data = yaml.safe_load(Path(load_problem("P2").source).read_text(encoding="utf-8"))
    data.update(name="P2_bottle1", horizon=4, goal=[["bottle1", "on", "table1"]])
    data.pop("optimal_length", None)
    path = tmp_path / "p2-bottle1.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return load_problem(path)


@pytest.mark.parametrize("seed", [0, 1])
def test_llm_mcts_solves_the_smallest_case_when_the_replies_start_with_the_right_actions(
    tmp_path: Path, seed: int
) -> None:
    problem = _smallest_case(tmp_path)
    plan = (Pick("bottle1"), Place("bottle1", "on", "table1"))
    backend = PlanFollowingBackendDouble(plan)
    # the prompt without occlusion predicates: only symbolic literals are computed per node,
    # which is all the plan-following double reads
    settings = with_overrides(RunSettings(), ["prompt.occlusion_predicates=false"])
    result = LlmMctsPlanner(LLMProposer(backend), settings).solve(problem, seed, 60.0)
    data = json.loads(json.dumps(result.to_json()))
    assert data["success"] is True and data["termination"] == "goal", data["termination"]
    assert data["planner"] == "llm-mcts"
    assert [step["action"] for step in data["plan"]] == [list(a.as_tuple()) for a in plan]
    assert replay_result_json(problem, data).reached_goal
    prior = data["details"]["prior"]
    calls = data["details"]["llm_calls_per_step"]
    # one call per node: the root, then each node a simulation creates (at most one each)
    assert data["counters"]["llm_calls"] == len(backend.requests) == prior["states"] == sum(calls)
    assert 2 <= sum(calls) <= data["counters"]["simulations"] + len(calls)
    assert prior["votes"] > 0 and prior["deadline_fallbacks"] == 0
    # the first reply of every query steered the root: the first request is the root's
    assert "('HandAvailable', '')" in backend.requests[0].user
    [query, *_] = data["details"]["llm_queries"]
    assert query["from_cache"] is False and len(data["details"]["llm_queries"]) == sum(calls)
    times = data["times"]
    assert times["predicates"] > 0 and times["proposer"] > 0
    assert times["predicates"] + times["proposer"] + times["tree_search"] <= times["total"]
