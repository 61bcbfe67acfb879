"""STaLM end to end on the PyBullet domain, with a scripted proposer in place of the model."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.errors import StalmError
from stalm.experiments.trap_check import trap_violations
from stalm.planners.registry import build_planner
from stalm.planners.stalm import StalmPlanner
from stalm.proposers.protocol import Proposal, ProposalRequest
from stalm.search import SearchSettings, SearchTree, TaskPlan, concretize, warm_started_uct
from stalm.trial.replay import replay_plan, replay_result_json
from stalm.world.problem import Problem
from tests.planners.doubles import ScriptedSuffixProposer, plain_settings

P2_PLAN = (
    Open("kitchen_door"),
    Pick("bottle2"),
    Place("bottle2", "on", "counter1"),
    Pick("bottle3"),
    Place("bottle3", "on", "counter1"),
    Pick("salter"),
    Place("salter", "right_of", "bottle1"),
)
P6_PLAN = (
    Open("kitchen_door"),
    Pick("beef_grill"),
    Place("beef_grill", "on", "sink_counter_left"),
    Pick("coke"),
    Place("coke", "on", "counter2"),
    Pick("wine"),
    Place("wine", "on", "counter2"),
    Pick("beef_grill"),
    Place("beef_grill", "on", "counter2"),
)


def _with_horizon(problem: Problem, horizon: int) -> Problem:
    return Problem(problem.spec.model_copy(update={"horizon": horizon}), problem.source)


def _solve(problem, plan, seed: int, budget: float = 240.0):
    proposer = ScriptedSuffixProposer(problem, plan)
    try:
        planner = StalmPlanner(proposer, plain_settings(30))
        return planner.solve(problem, seed, budget)
    finally:
        proposer.close()


def test_stalm_solves_p2_with_a_correct_task_plan_and_replay_confirms(problems) -> None:
    result = _solve(problems["P2"], P2_PLAN, seed=0)
    assert result.success and result.termination == "goal"
    assert [a.discrete for a in result.plan] == list(P2_PLAN)
    data = json.loads(json.dumps(result.to_json()))
    report = replay_result_json(problems["P2"], data)
    assert report.reached_goal and report.steps_executed == len(P2_PLAN)
    assert result.counters.llm_calls == 1 and result.times.total > 0


@pytest.mark.slow
def test_stalm_with_a_correct_p6_plan_never_breaks_the_grill_trap(problems) -> None:
    # Since issue 41 the trap binds (no can fits on the walled counter with the grill at its
    # front). Given one correct plan again and again, the paper's STaLM now ends at the
    # horizon for seeds 0-6 (before, the arm reached over the grill and it solved 4 of 6):
    # Concretize's one draw per step leaves coke or wine in the front strip, and the best-Q
    # action puts the grill straight back on its goal (+3), the local optimum of §4.3. What
    # must hold whatever the search does: every executed step replays, none breaks the trap.
    problem = problems["P6"]
    result = _solve(problem, P6_PLAN, seed=0, budget=400.0)
    report = replay_plan(problem, problem.initial_state, list(result.plan))
    assert report.failed_step is None, report.reason
    assert report.steps_executed == len(result.plan) > 0
    assert trap_violations(problem, report.states) == ()


FAILS_AT_STEP_3 = (
    Open("kitchen_door"),
    Pick("bottle2"),
    Place("bottle2", "on", "counter1"),
    Pick("salter"),
)
"""P2: picking the salter while bottle3 still stands in front of it fails at step k = 3."""


def test_a_plan_failing_at_step_k_warms_the_tree_with_its_first_k_steps(problems) -> None:
    problem = problems["P2"]
    wrong = FAILS_AT_STEP_3
    domain = Domain.create(problem)
    try:
        rng = np.random.default_rng(0)
        root = problem.initial_state
        concrete = concretize(domain, root, [TaskPlan(wrong)], rng)
        plan = concrete.plans[0]
        assert not concrete.success and plan.failure == "lack_of_3d_understanding"
        assert plan.failed_step == 3 and len(plan.actions) == 3
        tree = SearchTree.for_root(domain, root)
        warm_started_uct(
            domain, root, concrete.plans, rng, settings=SearchSettings(budget=0), tree=tree
        )
        for step in plan.steps[:3]:
            assert step.outcome.state in tree, "the warm tree holds the first k steps"
    finally:
        domain.close()


@pytest.mark.slow
def test_search_still_solves_after_the_plan_fails_at_step_k(problems) -> None:
    problem = problems["P2"]
    # Of seeds 0-5, seed 4 solves with the least work: 141 simulations in five replanning
    # steps, about 35 s of CPU (seed 0: 57 s). Every step is seeded, so the wall budget only
    # has to stay far above that, also on a machine busy with other work.
    result = _solve(problem, FAILS_AT_STEP_3, seed=4, budget=600.0)
    assert result.success
    assert replay_plan(problem, problem.initial_state, list(result.plan)).reached_goal


@pytest.mark.slow
def test_same_seed_and_proposer_give_the_identical_plan(problems) -> None:
    # Two steps of the online loop are enough to repeat every seeded part: predicates, the
    # proposer, a failed Concretize (the plan lacks the OPEN) and 30 warm-started simulations
    # per step. A horizon of 2 ends the trial there instead of running to the goal.
    short = _with_horizon(problems["P2"], 2)
    first = _solve(short, P2_PLAN[1:], seed=4)
    second = _solve(short, P2_PLAN[1:], seed=4)
    assert len(first.plan) == 2 and first.counters.simulations > 0
    assert first.to_json()["plan"] == second.to_json()["plan"]
    assert first.success == second.success


def test_plain_uct_runs_the_same_loop_without_a_model(problems) -> None:
    planner = build_planner("uct", plain_settings(5))
    result = planner.solve(problems["P2"], seed=0, time_budget_s=8.0)
    assert planner.name == "uct" and result.planner == "uct"
    assert result.counters.llm_calls == 0 and result.counters.simulations > 0
    assert result.termination in {"goal", "timeout", "horizon"}
    assert len(result.states) == len(result.plan) + 1


@pytest.mark.slow
def test_the_executed_childs_subtree_is_kept_between_steps_and_can_be_switched_off(
    problems,
) -> None:
    """Tree reuse: every real step after the first starts from a root that already has the
    visits the last step's search gave it; with reuse off, each step starts from nothing."""
    kept = build_planner("uct", plain_settings(6))
    result = kept.solve(problems["P2"], seed=1, time_budget_s=20.0)
    reused = result.details.method.reused_root_visits
    assert len(result.plan) >= 2 and reused
    assert all(visits > 0 for visits in reused)
    fresh = build_planner("uct", plain_settings(6, ("execution.reuse_tree", False)))
    assert (
        fresh.solve(problems["P2"], seed=1, time_budget_s=8.0).details.method.reused_root_visits
        == ()
    )


class GoalCountDouble:
    """Stands in for the Domain in the execution rule: goal conjuncts true per state name."""

    def __init__(self, counts: dict[str, int]) -> None:
        self.counts = counts

    def goal_atoms_true(self, state) -> int:
        return self.counts.get(str(state), 0)


def test_the_progress_rule_executes_the_best_action_that_leads_to_goal_progress() -> None:
    """Root action 'a' has the higher Q but the tree knows no way on from it to a new goal
    conjunct; 'b' leads (two steps down) to one: 'progress' executes 'b'; with neither
    leading anywhere it executes nothing and the search goes on."""
    from stalm.domain.outcome import Outcome
    from stalm.planners.tree_step import _best_promising_action
    from stalm.search.tree import Edge
    from tests.search.synthetic import drawn, move, state

    s0, sa, sb, sg = state("s0"), state("sa"), state("sb"), state("sg")
    tree = SearchTree(s0, [move("a"), move("b")])
    ka, kb, kc = drawn("a", 1), drawn("b", 1), drawn("c", 1)
    tree.add_kappa(s0, move("a"), ka, Outcome(sa, 0.0, True))
    tree.add_kappa(s0, move("b"), kb, Outcome(sb, 0.0, True))
    tree.add_node(sa, [])
    tree.add_node(sb, [move("c")])
    tree.add_kappa(sb, move("c"), kc, Outcome(sg, 3.0, True))
    tree.backup([Edge(s0, move("a"), ka)], 5.0, 1.0, sa)
    tree.backup([Edge(s0, move("b"), kb), Edge(sb, move("c"), kc)], -6.0, 1.0)
    assert tree.node(s0).child(move("a")).q > tree.node(s0).child(move("b")).q
    assert _best_promising_action(tree, GoalCountDouble({"sg": 1})) == kb
    assert _best_promising_action(tree, GoalCountDouble({})) is None
    # progress is counted against the root: a root that already has the conjunct gains nothing
    assert _best_promising_action(tree, GoalCountDouble({"s0": 1, "sg": 1})) is None


def test_the_progress_rule_looks_below_every_feasible_kappa_of_an_action() -> None:
    """Action 'b' has two draws: the higher-Q one leads nowhere, the other (a different
    grasp or placement) leads to a goal conjunct. The rule executes 'b' with that draw
    rather than passing 'b' over."""
    from stalm.domain.outcome import Outcome
    from stalm.planners.tree_step import _best_promising_action
    from stalm.search.tree import Edge
    from tests.search.synthetic import drawn, move, state

    s0, s1, s2, sg = state("s0"), state("s1"), state("s2"), state("sg")
    tree = SearchTree(s0, [move("b")])
    k1, k2, kc = drawn("b", 1), drawn("b", 2), drawn("c", 1)
    tree.add_kappa(s0, move("b"), k1, Outcome(s1, 0.0, True))
    tree.add_kappa(s0, move("b"), k2, Outcome(s2, 0.0, True))
    tree.add_node(s1, [])
    tree.add_node(s2, [move("c")])
    tree.add_kappa(s2, move("c"), kc, Outcome(sg, 3.0, True))
    tree.backup([Edge(s0, move("b"), k1)], 5.0, 1.0, s1)
    tree.backup([Edge(s0, move("b"), k2), Edge(s2, move("c"), kc)], -6.0, 1.0)
    kappas = {k.kappa: k.q for k in tree.node(s0).child(move("b")).children}
    assert kappas[k1] > kappas[k2]
    assert _best_promising_action(tree, GoalCountDouble({"sg": 1})) == k2


def test_the_progress_rule_searches_on_a_counted_number_of_times_then_falls_back(
    problems,
) -> None:
    """With one simulation per search the tree cannot see a goal conjunct two actions away,
    so 'progress' searches on exactly ``search_rounds`` times and then executes the best-Q
    root action: a count, so the same seed decides the same on a fast or a slow machine."""
    settings = plain_settings(1, ("execution.rule", "progress"), ("execution.search_rounds", 3))
    result = build_planner("uct", settings).solve(problems["P2"], seed=0, time_budget_s=10.0)
    first = result.details.method.step_log[0]
    assert first.decision == "best_q_fallback"
    assert first.searches == 3
    assert first.tree.root_visits == 3
    again = build_planner("uct", settings).solve(problems["P2"], seed=0, time_budget_s=10.0)
    assert result.plan and again.plan and again.plan[0] == result.plan[0]


class NoPlanProposerDouble:
    """A planning proposer's double whose every search comes back empty (as Fast Downward's
    does on an unsolvable abstraction)."""

    name = "no-plan-test-double"
    takes_feedback = False

    def propose(self, request: ProposalRequest) -> Proposal:
        return Proposal(plans=(), no_plan=("the abstraction has no plan to the goal",))


def test_feedback_on_for_a_proposer_that_takes_none_is_refused_naming_it(problems) -> None:
    """A proposer states whether it reads ``request.feedback``; STaLM will not run feedback
    into one that would drop it, and says which proposer and what to switch off."""
    settings = plain_settings(2, ("execution.feedback", True))
    with pytest.raises(StalmError, match="no-plan-test-double takes no feedback"):
        StalmPlanner(NoPlanProposerDouble(), settings).solve(problems["P2"], 0, 1.5)


def test_a_proposer_that_found_no_plan_counts_as_no_plan_not_unparseable(problems) -> None:
    """Figure 5 tells a search that found nothing from a reply that could not be read."""
    settings = plain_settings(2, ("prompt.occlusion_predicates", False))
    result = StalmPlanner(NoPlanProposerDouble(), settings).solve(problems["P2"], 0, 1.5)
    assert result.llm_plan_failures.get("no_plan", 0) >= 1
    assert "unparseable" not in result.llm_plan_failures
    first = result.details.method.step_log[0].proposals[0].plans[0]
    assert first.kind == "no_plan" and first.unparseable is None
    assert first.no_plan == "the abstraction has no plan to the goal"


def test_a_proposer_of_the_old_form_is_refused_naming_what_it_lacks() -> None:
    class OldFormProposerDouble:
        """Written for the positional propose(problem, state, ...) and no takes_feedback."""

        name = "old-form-test-double"

        def propose(self, problem, state, literals, n, seed, deadline=None):
            raise AssertionError("never asked")

    with pytest.raises(
        StalmError, match="OldFormProposerDouble is no task-plan proposer: it has no takes_feedback"
    ):
        StalmPlanner(OldFormProposerDouble())
