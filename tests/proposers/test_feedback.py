"""Geometric feedback: Concretize's failed steps become facts the symbolic proposer respects,
for as long as the part of the state they were about stays as it was."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.domain.params import Action, PickParams, PlaceParams
from stalm.motion.base_motion import BasePath
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.fast_downward import SymbolicProposer
from stalm.proposers.feedback import failed_steps
from stalm.proposers.feedback_memory import FeedbackMemory, grounded_in_tree, grounded_steps
from stalm.proposers.protocol import ProposalRequest
from stalm.search.concretize import ConcretePlan, ConcreteStep, TaskPlan
from stalm.search.tree import SearchTree
from stalm.world.state import Grasp, ObjectPose


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
    before = proposer.propose(ProposalRequest(problem, state, frozenset(literals), 5, seed=0))
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

    after = proposer.propose(
        ProposalRequest(problem, state, frozenset(literals), 5, seed=0, feedback=tuple(holding))
    )
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
        ProposalRequest(
            problem, root, frozenset(initial_literals("P2")), 5, seed=0, feedback=tuple(learned)
        )
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

    # the same rule seen first with the door closed, then with it open: the copy that holds
    # in more states (the door open or closed) is kept
    narrow = replace(learned[0], open_doors=frozenset())
    memory = FeedbackMemory.empty()
    assert memory.learn([narrow]) == 1
    assert memory.holding_in(state) == ()  # the door is open in ``state``
    assert memory.learn(learned) == 0  # not a new lesson ...
    assert memory.holding_in(state) == tuple(learned)  # ... but it holds there now
    assert memory.holding_in(problem.initial_state) == tuple(learned)


def test_a_rule_that_leaves_no_plan_is_dropped(problems, initial_literals) -> None:
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
        ProposalRequest(
            problem, state, frozenset(initial_literals("P2")), 3, seed=0, feedback=tuple(learned)
        )
    )
    assert proposal.plans
    assert all(p[-1] == Place("salter", "right_of", "bottle1") for p in proposal.plans)


# P5's counter1 (walls at the back and sides): poses at its front and in its back pocket
P5_FRONT = ObjectPose.make(-4.49, 3.45, 1.03, 3.141593)
P5_BACK = ObjectPose.make(-4.74, 3.52, 1.03, 3.141593)
P5_SIDE = ObjectPose.make(-4.46, 3.64, 1.03, 3.141593)


def _crowded(problem, obj: str, others: dict[str, ObjectPose]):
    """The rule learned when placing ``obj`` on P5's counter1 found no spot beside ``others``
    (resting there at the given poses)."""
    state = problem.initial_state.with_changes(poses=others)
    blockers = (*sorted(others), "counter1_wall_left")
    why = Infeasibility("no_placement", f"placements of '{obj}' on 'counter1' collide", blockers)
    plan = (Pick(obj), Place(obj, "on", "counter1"))
    (learned,) = failed_steps(problem, [_failed_plan(state, plan, 1, why)])
    assert learned.forbids == (obj, "on", "counter1", "counter1")
    assert learned.besides == tuple(sorted(others))
    return learned


def _grounded(state, action: Place, placement: ObjectPose) -> ConcretePlan:
    """A one-step plan whose placement Concretize grounded (feasible) in ``state``."""
    params = Action(action, PlaceParams(BasePath(()), placement, (), ()))
    after = state.with_changes(poses={action.obj: placement}, held=None)
    step = ConcreteStep(state, action, params, Outcome(after, 0.0, True))
    return ConcretePlan(0, TaskPlan((action,)), (step,), False, "partially_achieved_goal")


def _last_placed_on(plan, region: str) -> list[str]:
    """The objects a task plan leaves on ``region``, in the order they were last put there."""
    order: list[str] = []
    for action in plan:
        if isinstance(action, Place) and action.direction == "on" and action.ref == region:
            order = [o for o in order if o != action.obj] + [action.obj]
    return order


def test_contradicting_rules_are_given_up_in_orders_drawn_from_the_seed(
    problems, initial_literals
) -> None:
    """P5: four rules about counter1, each learned from one draw, contradict each other (no
    can after the grill, no grill after a can): the proposer must give some up. Giving them
    up newest first kept the two wrong ones (learned first) and proposed the sprite after the
    grill at every query, failing the same way each time. Each plan of the batch now gives
    them up in its own order drawn from the seed: the batch holds several resolutions, the
    grill last among them, and the same seed gives the same batch."""
    problem = problems["P5"]
    memory = FeedbackMemory.empty()
    learned = [
        _crowded(problem, "coke", {"beef_grill": P5_FRONT}),
        _crowded(problem, "beef_grill", {"sprite": P5_FRONT}),
        _crowded(problem, "beef_grill", {"coke": P5_FRONT}),
        _crowded(problem, "sprite", {"beef_grill": P5_FRONT}),
    ]
    assert memory.learn(learned) == 4
    assert memory.learn(learned[-1:]) == 0  # the same lesson is kept once
    holding = memory.holding_in(problem.initial_state)
    proposer = SymbolicProposer()
    literals = initial_literals("P5")
    state = problem.initial_state
    proposal = proposer.propose(
        ProposalRequest(problem, state, frozenset(literals), 5, seed=0, feedback=tuple(holding))
    )
    last = [_last_placed_on(plan, "counter1")[-1] for plan in proposal.plans]
    assert "beef_grill" in last and len(set(last)) > 1, last
    again = proposer.propose(
        ProposalRequest(problem, state, frozenset(literals), 5, seed=0, feedback=tuple(holding))
    )
    assert again.plans == proposal.plans


def test_an_arm_blocked_by_what_stands_on_the_region_is_the_crowding_rule(
    problems, initial_literals
) -> None:
    """P5's binding trap: with the grill at the front of counter1, placing a can there fails
    with the arm hitting the grill (it is too tall to reach over), not for want of a spot.
    That failure says the same as a crowded region: not there while the grill is there,
    wherever exactly. Scoped to the grill's exact pose, as an occlusion, it never applied
    where the proposer planned from (the grill still off the counter), and Fast Downward put
    the grill first at every query."""
    problem = problems["P5"]
    state = problem.initial_state.with_changes(poses={"beef_grill": P5_FRONT})
    why = Infeasibility("arm_collision", "placing 'coke' collides", ("beef_grill",))
    plan = (Pick("coke"), Place("coke", "on", "counter1"))
    (learned,) = failed_steps(problem, [_failed_plan(state, plan, 1, why)])
    assert learned.forbids == ("coke", "on", "counter1", "counter1")
    assert learned.besides == ("beef_grill",)
    assert learned.exact is not None
    assert learned.exact.facts == (
        GroundLiteral("PlaceOccludedBy", ("coke", "on", "counter1", "beef_grill")),
    )
    memory = FeedbackMemory.empty()
    memory.learn([learned])
    proposal = SymbolicProposer().propose(
        ProposalRequest(
            problem,
            problem.initial_state,
            frozenset(initial_literals("P5")),
            3,
            seed=0,
            feedback=tuple(memory.holding_in(problem.initial_state)),
        )
    )
    assert proposal.plans
    for task_plan in proposal.plans:
        on_counter = _last_placed_on(task_plan, "counter1")
        assert on_counter.index("coke") < on_counter.index("beef_grill"), task_plan


def test_refuted_rules_leave_the_contradiction_to_the_true_ones(problems, initial_literals) -> None:
    """The grill grounded on counter1 beside a can refutes both 'no grill after a can' rules:
    the two left (no can after the grill) make every plan put the grill last."""
    problem = problems["P5"]
    memory = FeedbackMemory.empty()
    memory.learn(
        [
            _crowded(problem, "coke", {"beef_grill": P5_FRONT}),
            _crowded(problem, "beef_grill", {"sprite": P5_FRONT}),
            _crowded(problem, "beef_grill", {"coke": P5_FRONT}),
            _crowded(problem, "sprite", {"beef_grill": P5_FRONT}),
        ]
    )
    place = Place("beef_grill", "on", "counter1")
    beside_cans = problem.initial_state.with_changes(poses={"coke": P5_BACK, "sprite": P5_SIDE})
    assert memory.observe(grounded_steps(problem, [_grounded(beside_cans, place, P5_FRONT)])) == 2
    holding = memory.holding_in(problem.initial_state)
    assert [step.forbids[0] for step in holding if step.forbids] == ["coke", "sprite"]
    proposal = SymbolicProposer().propose(
        ProposalRequest(
            problem,
            problem.initial_state,
            frozenset(initial_literals("P5")),
            3,
            seed=0,
            feedback=tuple(holding),
        )
    )
    assert proposal.plans
    for plan in proposal.plans:
        assert _last_placed_on(plan, "counter1")[-1] == "beef_grill", plan


def test_a_grounded_placement_refutes_a_rule_and_leaves_what_was_observed(problems) -> None:
    """'No grill on counter1 while the coke is there' came from a coke drawn at the front; a
    grill placed there with the coke in the back pocket refutes it. What is left is the
    failure at the poses it was seen at, which lapses once the coke moves."""
    problem = problems["P5"]
    rule = _crowded(problem, "beef_grill", {"coke": P5_FRONT})
    memory = FeedbackMemory.empty()
    memory.learn([rule])
    at_front = problem.initial_state.with_changes(poses={"coke": P5_FRONT})
    assert memory.holding_in(at_front) == (rule,)

    in_back = problem.initial_state.with_changes(poses={"coke": P5_BACK})
    place = Place("beef_grill", "on", "counter1")
    # a placement elsewhere, or with the coke off the counter, refutes nothing
    on_counter3 = ObjectPose.make(4.6, 3.2, 1.03, 0.0)
    elsewhere = _grounded(in_back, Place("beef_grill", "on", "counter3"), on_counter3)
    coke_away = _grounded(problem.initial_state, place, P5_FRONT)
    assert memory.observe(grounded_steps(problem, [elsewhere, coke_away])) == 0
    assert memory.observe(grounded_steps(problem, [_grounded(in_back, place, P5_FRONT)])) == 1

    (observed,) = memory.holding_in(at_front)
    assert observed.forbids is None
    assert observed.facts == (
        GroundLiteral("PlaceFailed", ("beef_grill", "on", "counter1", "counter1")),
    )
    assert memory.holding_in(in_back) == ()  # the coke moved: the observation lapses
    # seen again at another pose, the refuted rule stays refuted: that pose is kept instead
    assert memory.learn([_crowded(problem, "beef_grill", {"coke": P5_SIDE})]) == 1
    at_side = problem.initial_state.with_changes(poses={"coke": P5_SIDE})
    assert [step.forbids for step in memory.holding_in(at_side)] == [None]


def test_a_placement_the_search_tree_found_feasible_refutes_a_rule(problems) -> None:
    """The simulations' transitions are evidence too: a grill placed on counter1 beside the
    coke deep in the tree (as the search's own draw, then perhaps executed) refutes 'no grill
    on counter1 while the coke is there'; an infeasible one does not."""
    problem = problems["P5"]
    memory = FeedbackMemory.empty()
    memory.learn([_crowded(problem, "beef_grill", {"coke": P5_FRONT})])
    in_back = problem.initial_state.with_changes(poses={"coke": P5_BACK})
    place = Place("beef_grill", "on", "counter1")
    tree = SearchTree(problem.initial_state, [Pick("coke")])
    tree.add_node(in_back, [place])
    why = Infeasibility("no_placement", "no room", ("coke",))
    tree.add_kappa(in_back, place, why, Outcome(in_back, -6.0, False, why))
    assert memory.observe(grounded_in_tree(problem, tree)) == 0
    (step,) = _grounded(in_back, place, P5_FRONT).steps
    tree.add_kappa(in_back, place, step.kappa, step.outcome)
    assert memory.observe(grounded_in_tree(problem, tree)) == 1
    at_front = problem.initial_state.with_changes(poses={"coke": P5_FRONT})
    assert [step.forbids for step in memory.holding_in(at_front)] == [None]


def test_a_rule_learned_after_its_counterexample_is_refuted_at_once(problems) -> None:
    problem = problems["P5"]
    memory = FeedbackMemory.empty()
    in_back = problem.initial_state.with_changes(poses={"coke": P5_BACK})
    placed = _grounded(in_back, Place("beef_grill", "on", "counter1"), P5_FRONT)
    assert memory.observe(grounded_steps(problem, [placed])) == 0
    memory.learn([_crowded(problem, "beef_grill", {"coke": P5_FRONT})])
    at_front = problem.initial_state.with_changes(poses={"coke": P5_FRONT})
    assert [step.forbids for step in memory.holding_in(at_front)] == [None]


def test_a_blocked_pick_is_a_rule_about_the_blockers_on_its_region(problems) -> None:
    """salter's pick collided with bottle2, which rests on salter's counter: while bottle2 is
    on counter2, wherever exactly, salter is not picked (putting bottle2 back down there is no
    way past it). What was observed is the occlusion at bottle2's pose, cleared by moving it."""
    problem = problems["P2"]
    state = problem.initial_state
    why = Infeasibility("arm_collision", "reaching for 'salter' collides", ("bottle2", "counter2"))
    (learned,) = failed_steps(problem, [_failed_plan(state, (Pick("salter"),), 0, why)])
    # the counter is static scenery, not something a plan can move: only bottle2 is named
    assert learned.forbids_pick == ("salter", "counter2")
    assert learned.besides == ("bottle2",)
    assert learned.exact is not None
    assert learned.exact.facts == (GroundLiteral("PickOccludedBy", ("salter", "bottle2")),)
    assert {obj for obj, _ in learned.exact.support} == {"salter", "bottle2"}
    assert learned.holds_in(state) and learned.exact.holds_in(state)
    put_back = state.with_changes(poses={"bottle2": ObjectPose.make(-4.7, -1.3, 1.03, 0.0)})
    assert learned.holds_in(put_back)  # the rule: bottle2 anywhere on counter2
    assert not learned.exact.holds_in(put_back)  # the observation: bottle2 where it was
    salter_moved = state.with_changes(poses={"salter": ObjectPose.make(9.0, 9.0, 1.0, 0.0)})
    assert not learned.holds_in(salter_moved)


def _grill_region_at_first_pick_of(plan, obj: str, start: str) -> str | None:
    """Where a P5 task plan has put the grill (``start`` at the start) when it first picks
    ``obj``; None if it never picks it."""
    where = start
    for action in plan:
        if isinstance(action, Pick) and action.obj == obj:
            return where
        if isinstance(action, Pick) and action.obj == "beef_grill":
            where = "hand"
        elif isinstance(action, Place) and action.obj == "beef_grill":
            where = action.ref if action.direction == "on" else f"beside {action.ref}"
    return None


def test_a_pick_rule_keeps_the_occluder_off_the_region_and_a_grounded_pick_refutes_it(
    problems, initial_literals
) -> None:
    """P5: the coke's pick collided with the grill on counter2. Holding the grill (and with the
    rule that no can goes on counter1 after it), the proposer put the grill back down on
    counter2 before picking the coke in some plans, a pick Concretize then finds blocked
    again; with the rule it takes the grill elsewhere. A pick of the coke grounded with the
    grill on counter2 (drawn aside) refutes the rule."""
    problem = problems["P5"]
    state = problem.initial_state
    why = Infeasibility("arm_collision", "reaching for 'coke' collides", ("beef_grill",))
    (rule,) = failed_steps(problem, [_failed_plan(state, (Pick("coke"),), 0, why)])
    assert (rule.forbids_pick, rule.besides) == (("coke", "counter2"), ("beef_grill",))
    memory = FeedbackMemory.empty()
    memory.learn([rule, _crowded(problem, "coke", {"beef_grill": P5_FRONT})])
    grasp = Grasp.make("beef_grill", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    holding = state.with_changes(remove="beef_grill", held=grasp)
    literals = {
        literal
        for literal in initial_literals("P5")
        if "beef_grill" not in literal.args and literal.name != "HandAvailable"
    } | {GroundLiteral("RobotHolding", ("beef_grill",))}
    proposal = SymbolicProposer().propose(
        ProposalRequest(
            problem,
            holding,
            frozenset(literals),
            5,
            seed=0,
            feedback=tuple(memory.holding_in(holding)),
        )
    )
    assert proposal.plans
    for plan in proposal.plans:
        assert _grill_region_at_first_pick_of(plan, "coke", "hand") not in ("counter2", None)

    aside = state.with_changes(poses={"beef_grill": ObjectPose.make(-4.6, -1.25, 1.03, 3.14)})
    pick = Pick("coke")
    grasp = Grasp.make("coke", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    params = Action(pick, PickParams(BasePath(()), 0.0, 0.0, grasp, (), ()))
    after = aside.with_changes(remove="coke", held=grasp)
    step = ConcreteStep(aside, pick, params, Outcome(after, 0.0, True))
    grounded = ConcretePlan(0, TaskPlan((pick,)), (step,), False, "partially_achieved_goal")
    assert memory.observe(grounded_steps(problem, [grounded])) == 1
    holding_now = memory.holding_in(state)
    assert all(step.forbids_pick is None for step in holding_now)
    occlusion = GroundLiteral("PickOccludedBy", ("coke", "beef_grill"))
    assert [step.facts for step in holding_now if step.forbids is None] == [(occlusion,)]


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
        ProposalRequest(
            problem, problem.initial_state, frozenset(initial_literals("P2")), 3, seed=0
        )
    )
    assert proposal.plans == ()
    assert proposal.no_plan and "time limit" in proposal.no_plan[0]
    assert proposal.unparseable == ()
