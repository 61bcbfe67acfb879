"""What P1-P6 say of their own geometry, checked where solves meet it.

P2's "the salter stands behind two bottles; clear them", P3's "boxed in by the rows in front"
and P1's "the closed door is in the way of every cross-room move" are claims a solve could get
round, as the grill trap's once was. The checks must name a plan that gets round them (forged
here), and find none in real solves: the committed Table 2 records and, in the slow tests,
fresh solves of seeds nobody looked at.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from stalm.domain.actions import Pick
from stalm.experiments.claim_check import (
    check_replay,
    check_results,
    door_violations,
    initial_occluders,
    occluder_violations,
)
from stalm.experiments.trap_check import FirstProposal, first_proposal
from stalm.planners.registry import build_planner
from stalm.trial.replay import replay_plan, replay_result_json
from stalm.world.problem import load_problem
from stalm.world.state import Grasp, ObjectPose
from tests.flat_settings import settings_of

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"
TABLE2 = RESULTS / "issue27" / "stalm-symbolic-after-1a3cc06.jsonl"
"""The `stalm-symbolic` row of Table 2: 10 solved trials of each of P1-P6 (P5's and P6's on
the grill before the trap bound, which the checks skip: another problem's hash)."""


def test_the_descriptions_occluders_are_what_the_predicates_find() -> None:
    # P2: "The salter stands behind two bottles on counter2; clear them, open the door"
    assert initial_occluders(load_problem("P2"))["salter"] == {"bottle2", "bottle3", "kitchen_door"}


def test_a_pick_past_a_standing_occluder_or_a_closed_door_is_named() -> None:
    problem = load_problem("P2")
    start = problem.initial_state
    occluders = {"salter": frozenset({"bottle2", "bottle3", "kitchen_door"})}
    doors = frozenset({"kitchen_door"})
    assert occluder_violations(occluders, doors, (start,), (Pick("salter"),)) == (
        "step 1: salter picked with bottle2 still in the way",
        "step 1: salter picked with bottle3 still in the way",
        "step 1: salter picked with kitchen_door closed",
    )
    # bottle2 moved 0.2 m, bottle3 still there, the door open
    p = start.pose("bottle2")
    cleared = start.with_changes(
        poses={"bottle2": ObjectPose.make(p.x + 0.2, p.y, p.z, p.yaw)}, open_door="kitchen_door"
    )
    assert occluder_violations(
        occluders, doors, (start, cleared), (Pick("bottle1"), Pick("salter"))
    ) == ("step 2: salter picked with bottle3 still in the way",)


def test_a_replayed_plan_that_picks_past_an_occluder_is_named() -> None:
    """The check reads a replay's executed actions (each a discrete action with its
    parameters): a report whose first action picks the salter is named."""
    problem = load_problem("P2")
    record = json.loads(
        next(line for line in TABLE2.read_text().splitlines() if '"problem": "P2"' in line)
    )
    report = replay_result_json(problem, record)
    salter = next(i for i, a in enumerate(report.actions) if a.discrete == Pick("salter"))
    forged = dataclasses.replace(
        report,
        states=(problem.initial_state, *report.states[salter + 1 :]),
        actions=report.actions[salter:],
    )
    occluders = {"salter": frozenset({"bottle2", "bottle3", "kitchen_door"})}
    check = check_replay(problem, occluders, forged)
    assert check.picks_checked == 1
    assert "step 1: salter picked with bottle2 still in the way" in check.violations


def test_a_cross_room_move_with_the_door_closed_is_named() -> None:
    problem = load_problem("P1")
    spec = problem.spec
    start = problem.initial_state
    # salter1 starts on counter1, in the kitchen; put it on table1, in the hall
    held = start.with_changes(
        remove="salter1", held=Grasp.make("salter1", (0, 0, 0.1), (0, 0, 0, 1))
    )
    table = spec.region("table1")
    down = held.with_changes(
        poses={"salter1": ObjectPose.make(*table.center, table.top, 0.0)}, held=None
    )
    assert door_violations(problem, (start, held, down)) == (
        "step 2: salter1 carried from the kitchen to the hall with every door closed",
    )
    opened = down.with_changes(open_door="kitchen_door")
    assert door_violations(problem, (start, held, opened)) == ()


def test_the_committed_solves_meet_every_claim(tmp_path) -> None:
    lines = [line for line in TABLE2.read_text().splitlines() if '"problem": "P2"' in line]
    sample = tmp_path / "p2.jsonl"
    sample.write_text("\n".join(lines[:3]) + "\n")
    checked = check_results(sample)
    assert checked.skipped == ()
    checks = checked.checks
    assert [c.problem for c in checks] == ["P2"] * 3
    assert all(c.reached_goal and c.violations == () for c in checks)
    # the salter and both bottles (behind the closed door) were picked: the claim was met,
    # not skipped
    assert all(c.picks_checked >= 3 for c in checks), [c.picks_checked for c in checks]


def test_the_first_proposal_of_p5_puts_the_grill_first_and_fails() -> None:
    # Fast Downward knows nothing of the walls: its first plans put the grill first, and
    # Concretize finds each of them infeasible (the paper's "lack of 3D understanding")
    record = json.loads((RESULTS / "issue41" / "stalm-symbolic.jsonl").read_text().splitlines()[0])
    first = first_proposal(load_problem(record["problem"]), record)
    assert first is not None
    assert first.plans >= 1
    assert first.grill_first == first.grill_first_failed == first.plans


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 12])
@pytest.mark.parametrize("name", ["P1", "P2", "P3", "P4"])
def test_a_fresh_solve_meets_every_claim(name, seed) -> None:
    problem = load_problem(name)
    planner = build_planner("stalm", settings_of(proposer="symbolic"))
    result = planner.solve(problem, seed=seed, time_budget_s=problem.spec.time_budget_s)
    assert result.success, result.termination
    report = replay_plan(problem, problem.initial_state, list(result.plan))
    check = check_replay(problem, initial_occluders(problem), report, seed)
    assert check.reached_goal
    assert check.picks_checked >= 1
    assert check.violations == ()


def test_records_of_another_version_of_a_problem_are_named_not_checked(tmp_path) -> None:
    # Table 2's P5 records were solved before the trap bound: another problem hash
    lines = [line for line in TABLE2.read_text().splitlines() if '"problem": "P5"' in line]
    sample = tmp_path / "p5.jsonl"
    sample.write_text("\n".join(lines[:2]) + "\n")
    checked = check_results(sample)
    assert checked.checks == ()
    assert len(checked.skipped) == 2
    assert all("P5 seed" in why for why in checked.skipped)
    from stalm.experiments.trap_check import check_results as trap_results

    assert trap_results(sample, {"P5": load_problem("P5")}) == []  # not a crash


def test_the_fidelity_reads_only_what_it_understands() -> None:
    problem = load_problem("P5")
    assert first_proposal(problem, {"details": {"step_log": ["not a step"]}}) is None
    assert first_proposal(problem, {"details": {"step_log": [{"proposals": [{}]}]}}) is None
    plans = [
        {
            "actions": [
                ["place", "beef_grill", "on", "counter1"],
                ["place", "coke", "on", "counter1"],
            ],
            "failed_step": 1,
        },
        {
            "actions": [
                ["place", "beef_grill", "on", "counter1"],
                ["place", "coke", "on", "counter1"],
            ],
            "failed_step": None,
            "reached_goal": False,
        },  # ran short, Concretize did not stop it
        {"no_plan": "Fast Downward found none"},  # no actions: not a plan
    ]
    record = {"details": {"step_log": [{"proposals": [{"plans": plans}]}]}}
    assert first_proposal(problem, record) == FirstProposal(2, 2, 1)
