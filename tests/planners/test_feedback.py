"""Geometric feedback: Concretize's failed steps become facts the symbolic proposer respects,
for as long as the part of the state they were about stays as it was."""

from __future__ import annotations

import numpy as np

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.planners.feedback import FeedbackMemory, failed_steps
from stalm.planners.symbolic import SymbolicProposer
from stalm.predicates.literals import GroundLiteral
from stalm.search.concretize import ConcretePlan, ConcreteStep, TaskPlan
from stalm.world.state import ObjectPose


def _failed_plan(state, actions, step, why) -> ConcretePlan:
    """A task plan whose step ``step`` ψ found infeasible, as Concretize reports it (the steps
    before it are not needed by the feedback, which reads only the failed one)."""
    failed = ConcreteStep(state, actions[step], why, Outcome(state, -6.0, False, why))
    return ConcretePlan(
        0,
        TaskPlan(tuple(actions)),
        (failed,),
        False,
        "lack_of_3d_understanding",
        str(why),
        failed_step=step,
    )


def test_a_failed_placement_is_no_longer_proposed_and_lapses_when_its_context_changes(
    problems, initial_literals
) -> None:
    problem = problems["P2"]
    state = problem.initial_state
    literals = initial_literals("P2")
    proposer = SymbolicProposer()
    target = Place("bottle2", "on", "table1")
    before = proposer.propose(problem, state, literals, 5, seed=0)
    assert any(target in plan for plan in before.plans)

    # table1 is empty: a placement that finds no spot there hit only static scenery
    why = Infeasibility("no_placement", "no free spot for 'bottle2' on 'table1'", ("table1",))
    plan = (Open("kitchen_door"), Pick("bottle2"), target)
    learned = failed_steps(problem, [_failed_plan(state, plan, 2, why)])
    assert len(learned) == 1
    assert learned[0].facts == (
        GroundLiteral("PlaceFailed", ("bottle2", "on", "table1", "table1")),
    )
    assert learned[0].forbids is None and learned[0].support == ()
    memory = FeedbackMemory.empty()
    assert memory.learn(learned) == 1
    assert memory.learn(learned) == 0  # the same lesson is kept once
    holding = memory.holding_in(state)
    assert holding == learned

    after = proposer.propose(problem, state, literals, 5, seed=0, feedback=holding)
    assert after.plans
    assert all(target not in proposed for proposed in after.plans)

    # learned with the door closed, it lapses once the door is open (a route may exist now);
    # learned with it open, it also holds while the door is closed (one more obstacle)
    assert memory.holding_in(state.with_changes(open_door="kitchen_door")) == ()
    deeper = failed_steps(
        problem, [_failed_plan(state.with_changes(open_door="kitchen_door"), plan, 2, why)]
    )
    assert deeper[0].holds_in(state)


def test_no_room_beside_an_object_is_a_rule_about_that_object_being_there(
    problems, initial_literals, domain_factory
) -> None:
    """bottle3 found no spot on table1 beside bottle2 (put there first): while bottle2 is on
    table1, wherever exactly, the proposer does not put bottle3 there too."""
    problem = problems["P2"]
    domain = domain_factory("P2")
    rng = np.random.default_rng(0)
    state = problem.initial_state
    for action in (Open("kitchen_door"), Pick("bottle2"), Place("bottle2", "on", "table1")):
        for _ in range(10):
            _, outcome = domain.sample_and_step(state, action, rng)
            if outcome.feasible:
                break
        assert outcome.feasible
        state = outcome.state
    why = Infeasibility(
        "no_placement", "placements of 'bottle3' on 'table1' collide", ("bottle2", "table1")
    )
    plan = (Pick("bottle3"), Place("bottle3", "on", "table1"))
    learned = failed_steps(problem, [_failed_plan(state, plan, 1, why)])
    assert learned[0].forbids == ("bottle3", "on", "table1", "table1")
    assert learned[0].besides == ("bottle2",)
    assert learned[0].holds_in(problem.initial_state)  # a rule, not a pose

    root = problem.initial_state
    proposal = SymbolicProposer().propose(
        problem, root, initial_literals("P2"), 5, seed=0, feedback=learned
    )
    assert proposal.plans
    for proposed in proposal.plans:
        on_table1: set[str] = set()
        for action in proposed:
            if isinstance(action, Pick):
                on_table1.discard(action.obj)
            elif isinstance(action, Place) and action.ref == "table1":
                assert not (action.obj == "bottle3" and "bottle2" in on_table1), proposed
                on_table1.add(action.obj)


def test_rules_that_leave_no_plan_are_dropped_newest_first(problems, initial_literals) -> None:
    """A rule against the goal's own placement (generalised from an unlucky draw) would make
    the task unsolvable: the proposer drops it and still proposes plans."""
    problem = problems["P2"]
    state = problem.initial_state
    why = Infeasibility(
        "no_placement", "placements of 'salter' beside 'bottle1' collide", ("bottle1", "table2")
    )
    plan = (Pick("salter"), Place("salter", "right_of", "bottle1"))
    learned = failed_steps(problem, [_failed_plan(state, plan, 1, why)])
    assert learned[0].forbids == ("salter", "right_of", "bottle1", "table2")
    proposal = SymbolicProposer().propose(
        problem, state, initial_literals("P2"), 3, seed=0, feedback=learned
    )
    assert proposal.plans
    assert all(p[-1] == Place("salter", "right_of", "bottle1") for p in proposal.plans)


def test_a_blocked_pick_becomes_an_occlusion_cleared_by_moving_the_blocker(problems) -> None:
    problem = problems["P2"]
    state = problem.initial_state
    why = Infeasibility("arm_collision", "reaching for 'salter' collides", ("bottle2", "counter2"))
    learned = failed_steps(problem, [_failed_plan(state, (Pick("salter"),), 0, why)])
    # the counter is static scenery, not something a plan can move: only bottle2 is named
    assert learned[0].facts == (GroundLiteral("PickOccludedBy", ("salter", "bottle2")),)
    assert {obj for obj, _ in learned[0].support} == {"salter", "bottle2"}
    assert learned[0].holds_in(state)
    moved = state.with_changes(poses={"bottle2": ObjectPose.make(9.0, 9.0, 1.0, 0.0)})
    assert not learned[0].holds_in(moved)


def test_precondition_failures_teach_nothing(problems) -> None:
    problem = problems["P2"]
    state = problem.initial_state
    why = Infeasibility("precondition", "the robot is not holding 'salter'")
    plan = (Place("salter", "on", "table2"),)
    assert failed_steps(problem, [_failed_plan(state, plan, 0, why)]) == ()


def test_a_fast_downward_time_out_is_an_empty_proposal_not_an_exception(
    problems, initial_literals
) -> None:
    problem = problems["P2"]
    proposal = SymbolicProposer(time_limit_s=0.001).propose(
        problem, problem.initial_state, initial_literals("P2"), 3, seed=0
    )
    assert proposal.plans == ()
    assert proposal.no_plan and "time limit" in proposal.no_plan[0]
    assert proposal.unparseable == ()
