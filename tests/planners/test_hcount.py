"""Hcount (Appendix C) against values worked out by hand from the initial predicates."""

from __future__ import annotations

import numpy as np
import pytest

from stalm.domain.actions import Open, Pick
from stalm.planners.hcount import (
    HcountLeafValue,
    hcount,
    hcount_value,
    objects_in_goal,
    occluder_set,
)
from stalm.planners.stalm import StalmPlanner, StalmSettings
from stalm.predicates.engine import PredicateEngine, PredicateSettings
from stalm.predicates.literals import GroundLiteral as L
from stalm.search import SearchSettings
from stalm.search.tree import Edge


def test_hcount_on_hand_made_literals(problems) -> None:
    p2 = problems["P2"]
    state = p2.initial_state
    literals = {
        L("PickOccludedBy", ("salter", "bottle2")),
        L("PickOccludedBy", ("salter", "bottle3")),
        L("PickOccludedBy", ("bottle3", "kitchen_door")),
        L("PlaceOccludedBy", ("salter", "right_of", "bottle1", "bottle1")),
        L("PickOccludedBy", ("bottle1", "salter")),  # circular: must not loop
    }
    # M = {bottle2, bottle3} from the pick, {bottle1} from the goal placement right_of bottle1,
    # then kitchen_door (occludes bottle3) and salter (occludes bottle1): 5; nothing in goal
    assert occluder_set(p2, literals, state) == {
        "bottle1",
        "bottle2",
        "bottle3",
        "kitchen_door",
        "salter",
    }
    assert objects_in_goal(p2, state) == set()
    assert hcount(p2, literals, state) == 5
    assert hcount_value(p2, literals, state) == 3.0 * 1 - 3.0 * 5


# Hand-worked from each scene (which objects stand in front of which, which room each goal
# region is in), then checked against the computed predicates:
EXPECTED = {
    # every goal move crosses the closed door; nothing else blocks: M = {door}
    "P1": ({"kitchen_door"}, set(), 1),
    # the salter is boxed in by bottle2 and bottle3 and behind the door
    "P2": ({"bottle2", "bottle3", "kitchen_door"}, set(), 3),
    # milk and coke stand behind the middle row (water, wine) and the front row (cocoa,
    # whiskey); counter2 is behind the door
    "P3": ({"cocoa", "whiskey", "water", "wine", "kitchen_door"}, set(), 5),
    # P2's salter plus a plate whose goal counter is behind the door
    "P4": ({"bottle2", "bottle3", "kitchen_door"}, set(), 3),
    # coke is behind the grill; both are behind the door
    "P5": ({"beef_grill", "kitchen_door"}, set(), 2),
    # the grill is already at its goal (|O_InGoal| = 1) but blocks coke and wine's placements
    "P6": ({"beef_grill", "kitchen_door"}, {"beef_grill"}, 1),
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_hcount_of_the_initial_states(problems, initial_literals, name) -> None:
    problem = problems[name]
    state = problem.initial_state
    literals = initial_literals(name)
    occluders, in_goal, value = EXPECTED[name]
    assert occluder_set(problem, literals, state) == occluders
    assert objects_in_goal(problem, state) == in_goal
    assert hcount(problem, literals, state) == value


def test_uct_hcount_runs(problems) -> None:
    planner = StalmPlanner(
        None, StalmSettings(search=SearchSettings(budget=2), leaf_value="hcount")
    )
    result = planner.solve(problems["P2"], seed=0, time_budget_s=5.0)
    assert planner.name == "uct-hcount" and result.counters.simulations >= 1
    leaves = result.details["hcount_leaves"]
    # the first root is computed from scratch; every leaf after it comes from its parent
    assert leaves["predicates_from_scratch"] >= 1
    assert leaves["predicates_brought_forward"] >= 1


def test_leaf_values_brought_forward_from_the_parent_equal_values_from_scratch(
    domain_factory,
) -> None:
    domain = domain_factory("P2")
    problem = domain.problem
    # Bringing predicates forward must equal computing them, whatever the sample counts; a
    # quarter of the default samples makes each from-scratch check about 3x cheaper.
    few_samples = PredicateSettings(
        pick_samples=4, placements_per_region=2, placement_draws=8, targeted_draws=10
    )
    engine = PredicateEngine(problem, domain.sim, domain.base_planner, few_samples)
    leaf_value = HcountLeafValue(problem, engine)
    rng = np.random.default_rng(5)

    def step(state, action):
        for _ in range(6):
            kappa, outcome = domain.sample_and_step(state, action, rng)
            if outcome.feasible:
                return Edge(state, action, kappa), outcome.state
        raise AssertionError(f"{action} never feasible")

    root = problem.initial_state
    opened_edge, opened = step(root, Open("kitchen_door"))
    # two siblings under the same parent: the parent's predicates must serve both unchanged
    picked1_edge, picked1 = step(opened, Pick("bottle1"))
    picked2_edge, picked2 = step(opened, Pick("bottle2"))
    values = {
        root: leaf_value(None, root, 0, rng),  # type: ignore[arg-type]
        opened: leaf_value(None, opened, 1, rng, arrival=opened_edge),  # type: ignore[arg-type]
        picked1: leaf_value(None, picked1, 2, rng, arrival=picked1_edge),  # type: ignore[arg-type]
        picked2: leaf_value(None, picked2, 2, rng, arrival=picked2_edge),  # type: ignore[arg-type]
    }
    assert (leaf_value.computed_from_scratch, leaf_value.brought_forward) == (1, 3)
    for state, estimate in values.items():
        scratch = hcount_value(problem, engine.compute(state).literals, state)
        assert estimate.value == scratch and estimate.goal_plan is None
    # holding bottle1 and holding bottle2 leave different occluders of the salter
    assert leaf_value.predicates(picked1).literals != leaf_value.predicates(picked2).literals
    # asked again (as a later real step's tree would), nothing is recomputed
    assert leaf_value(None, picked2, 2, rng).value == values[picked2].value  # type: ignore[arg-type]
    assert (leaf_value.computed_from_scratch, leaf_value.brought_forward) == (1, 3)
