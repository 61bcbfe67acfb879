"""The per-step record STaLM writes into its result (``details["step_log"]``): the task plans
and why each failed, the tree's root actions with N and Q and which the warm start put there,
and why the step executed what it executed."""

from __future__ import annotations

import json

import numpy as np

from stalm.domain.actions import Open, Pick
from stalm.planners.stalm import StalmPlanner
from stalm.search import SearchSettings, SearchTree, concretize, warm_started_uct
from stalm.trial.step_log import (
    DECISIONS,
    ProposalRound,
    RoundLessons,
    StepRecord,
    TreeRecord,
    task_plan_record,
    tree_record,
    warm_edges,
)
from stalm.world.problem import Problem
from tests.planners.doubles import ScriptedSuffixProposer, plain_settings
from tests.search.synthetic import detour, plan, state


def test_a_step_record_keeps_what_the_step_reached_and_leaves_out_the_rest() -> None:
    timed_out = StepRecord(step=3)
    timed_out.decision = "timeout"
    assert timed_out.to_json() == {"step": 3, "proposals": [], "tree": None, "decision": "timeout"}
    searched = StepRecord(step=0, proposals=[ProposalRound(0, 0, ())])
    tree = TreeRecord(4, 0, 3, 5, 2, 1, ())
    searched.tree, searched.decision, searched.searches = tree, "progress", 2
    searched.rules_refuted_by_tree, searched.executed = 0, 1
    entry = searched.to_json()
    assert list(entry) == [
        "step",
        "proposals",
        "tree",
        "decision",
        "searches",
        "rules_refuted_by_tree",
        "executed",
    ]
    assert entry["rules_refuted_by_tree"] == 0 and entry["executed"] == 1
    assert entry["proposals"] == [{"round": 0, "feedback_facts": 0, "plans": []}]
    assert entry["tree"]["root_visits"] == 4 and entry["tree"]["actions"] == []
    assert json.loads(json.dumps(entry)) == entry
    # a feedback round adds what it taught to its entry, after what the round offered
    searched.proposals.append(ProposalRound(1, 2, (), ("PickOccludedBy(a, b)",)))
    searched.learned(RoundLessons(("no_placement",), 1, 0))
    assert list(searched.to_json()["proposals"][1]) == [
        "round",
        "feedback_facts",
        "plans",
        "set_aside",
        "failures",
        "facts_learned",
        "rules_refuted",
    ]
    assert searched.proposals[0].lessons is None  # only the last round learned


def test_a_step_ends_by_executing_or_timing_out_and_says_so() -> None:
    timed_out = StepRecord(step=1)
    assert timed_out.timed_out() == "timeout"
    assert timed_out.to_json() == {"step": 1, "proposals": [], "tree": None, "decision": "timeout"}
    whole = StepRecord(step=0)
    actions = (Pick("salter"), Open("kitchen_door"))
    assert whole.executes(actions, "concretize_goal") is actions  # type: ignore[arg-type]
    assert (whole.decision, whole.executed) == ("concretize_goal", 2)
    searched = StepRecord(step=2)
    searched.decision = "progress"  # said by the search that chose the action
    assert searched.executes(()) == ()
    assert (searched.decision, searched.executed) == ("progress", 0)


def test_a_failed_plan_records_its_failed_step_kind_reason_and_the_warm_tree() -> None:
    mdp = detour().as_mdp()
    root = state("s0")
    rng = np.random.default_rng(0)
    concrete = concretize(mdp, root, [plan("a", "b", "c")], rng)
    record = task_plan_record(concrete.plans[0], ()).to_json()
    assert record["actions"] == [["a"], ["b"], ["c"]]
    assert record["failed_step"] == 2 and record["feasible_steps"] == 2
    assert record["kind"] == "lack_of_3d_understanding"
    assert record["reason"] == {"kind": "no_ik", "detail": "c#0 in s2", "blockers": []}

    tree = SearchTree.for_root(mdp, root)
    warm_started_uct(mdp, root, concrete.plans, rng, settings=SearchSettings(budget=0), tree=tree)
    shown = tree_record(tree, warm_edges(concrete.plans), visits_before=0).to_json()
    # the warm start visited a (and below it b); u was never tried and is only counted
    assert [a["action"] for a in shown["actions"]] == [["a"]]
    assert shown["root_actions"] == 2 and shown["untried_root_actions"] == 1
    first = shown["actions"][0]
    assert first["warm"] and first["n"] == 1 and first["feasible_kappas"] == 1
    assert [(c["action"], c["warm"], c["n"]) for c in first["children"]] == [(["b"], True, 1)]
    assert shown["root_visits"] == 1

    # after simulations, root actions the search found itself are not marked warm
    warm_started_uct(mdp, root, [], rng, settings=SearchSettings(budget=12), tree=tree)
    searched = tree_record(tree, warm_edges(concrete.plans), visits_before=1).to_json()
    by_name = {a["action"][0]: a for a in searched["actions"]}
    assert by_name["a"]["warm"] and "u" in by_name and not by_name["u"]["warm"]
    # (a simulation through e comes back to s0: the root counts that visit too)
    assert searched["root_visits"] >= 13 and searched["root_visits_before"] == 1


def test_stalm_writes_one_step_record_per_real_step(problems) -> None:
    # the plan lacks the OPEN: Concretize fails it, the warm-started tree decides (as in
    # test_same_seed_and_proposer_give_the_identical_plan); horizon 1 stops after one step
    p2 = problems["P2"]
    short = Problem(p2.spec.model_copy(update={"horizon": 1}), p2.source)
    proposer = ScriptedSuffixProposer(short, tuple(_p2_plan_without_open()))
    try:
        planner = StalmPlanner(
            proposer,
            # the scripted proposer reads no predicates: spare the occlusion motion planning
            plain_settings(10, ("prompt.occlusion_predicates", False)),
        )
        result = planner.solve(short, 4, 240.0)
    finally:
        proposer.close()
    log = json.loads(json.dumps(result.to_json()))["details"]["step_log"]
    assert len(log) == result.counters.replans == 1
    assert sum(step["executed"] for step in log) == len(result.plan)
    first = log[0]
    assert first["step"] == 0 and first["decision"] in DECISIONS
    plans = first["proposals"][0]["plans"]
    assert plans and all(p["kind"] is not None for p in plans)
    failed = plans[0]
    assert failed["actions"][0] == ["pick", "bottle2"]
    assert failed["reason"]["kind"] and isinstance(failed["reason"]["blockers"], list)
    tree = first["tree"]
    assert tree["root_visits"] >= 10 and tree["actions"]
    assert any(action["warm"] for action in tree["actions"])


def _p2_plan_without_open():
    from tests.planners.test_stalm import P2_PLAN

    return P2_PLAN[1:]
