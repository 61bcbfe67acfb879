"""Figure 5's failure kinds as the paper counts them: a first step the prompt's predicates
call occluded is a precondition violation, not a lack of 3D understanding."""

from __future__ import annotations

import numpy as np
import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.literals import GroundLiteral as L
from stalm.search.concretize import ConcretePlan, ConcreteStep, TaskPlan, concretize
from stalm.search.failure_kinds import figure5_kind, figure5_kinds, occluded_in
from stalm.trial.episode import Episode
from tests.search.synthetic import drawn, state

S = state("s0")
OCCLUDED = frozenset(
    {
        L("PickOccludedBy", ("salter", "bottle2")),
        L("PlaceOccludedBy", ("salter", "on", "counter2", "kitchen_door")),
    }
)


def failed_plan(actions, failed_step: int, kind: str, why: str = "base_path_blocked"):
    """A plan whose step ``failed_step`` ψ could not sample (the steps before it feasible)."""
    steps = [
        ConcreteStep(S, a, drawn("ok", i), Outcome(S, 0.0, True)) for i, a in enumerate(actions)
    ]
    infeasible = Infeasibility(why, "no motion")
    steps[failed_step] = ConcreteStep(
        S, actions[failed_step], infeasible, Outcome(S, -6.0, False, infeasible)
    )
    return ConcretePlan(
        0, TaskPlan(tuple(actions)), tuple(steps[: failed_step + 1]), False, kind, "d", failed_step
    )


def test_occlusion_is_read_from_the_literals() -> None:
    assert occluded_in(Pick("salter"), OCCLUDED)
    assert not occluded_in(Pick("bottle2"), OCCLUDED)
    assert occluded_in(Place("salter", "on", "counter2"), OCCLUDED)
    assert not occluded_in(Place("salter", "on", "table2"), OCCLUDED)
    assert not occluded_in(Open("kitchen_door"), OCCLUDED)


@pytest.mark.parametrize(
    ("actions", "step", "kind", "expected"),
    [
        # the prompt said picking the salter is occluded: planning it first ignores the input
        ((Pick("salter"),), 0, "lack_of_3d_understanding", "precondition_violation"),
        # the predicates allowed it, yet no motion was found: geometry the prompt cannot convey
        ((Pick("bottle2"),), 0, "lack_of_3d_understanding", "lack_of_3d_understanding"),
        # a later step is tried in a state whose predicates nobody computed: Concretize's kind
        (
            (Pick("bottle2"), Pick("salter")),
            1,
            "lack_of_3d_understanding",
            "lack_of_3d_understanding",
        ),
        # a symbolic precondition stays a precondition violation
        (
            (Place("salter", "on", "counter2"),),
            0,
            "precondition_violation",
            "precondition_violation",
        ),
    ],
)
def test_figure5_kind(actions, step: int, kind: str, expected: str) -> None:
    assert figure5_kind(failed_plan(actions, step, kind), OCCLUDED) == expected
    # a prompt without occlusion predicates told the model nothing: nothing is re-classified
    assert figure5_kind(failed_plan(actions, step, kind), ()) == kind


def test_unparseable_partial_and_successful_plans_keep_their_kind() -> None:
    unreadable = ConcretePlan(0, TaskPlan.unreadable("garbled"), (), False, "unparseable")
    assert figure5_kind(unreadable, OCCLUDED) == "unparseable"
    none_found = ConcretePlan(0, TaskPlan.none_found("unsolvable"), (), False, "no_plan")
    assert figure5_kind(none_found, OCCLUDED) == "no_plan"
    done = ConcretePlan(1, TaskPlan((Pick("salter"),)), (), True, None)
    assert figure5_kind(done, OCCLUDED) is None


def test_p2_plans_that_start_with_an_occluded_pick_count_as_precondition_violations(
    domain_factory,
) -> None:
    domain = domain_factory("P2")
    problem = domain.problem
    episode = Episode.begin(problem, 600.0)
    engine = PredicateEngine(problem, domain.sim, domain.base_planner)
    plans = [
        TaskPlan((Pick("salter"),)),  # boxed in by bottle2, bottle3 and the door: occluded
        TaskPlan((Open("kitchen_door"), Pick("salter"))),  # fails at step 1, not judged
        TaskPlan.unreadable("no plan list (plan = [...]) in the reply"),
        TaskPlan.none_found("Fast Downward found no plan in its time limit"),
    ]
    result = concretize(domain, episode.state, plans, np.random.default_rng(0))
    # the transition alone calls the first a lack of 3D understanding
    assert result.failures == (
        (0, "lack_of_3d_understanding"),
        (1, "lack_of_3d_understanding"),
        (2, "unparseable"),
        (3, "no_plan"),
    )
    with pytest.raises(RuntimeError, match="predicates"):
        episode.count_failures(result)
    episode.keep_predicates(engine)
    literals = episode.predicates().literals
    assert L("PickOccludedBy", ("salter", "bottle2")) in literals
    assert figure5_kinds(result, literals) == (
        "precondition_violation",
        "lack_of_3d_understanding",
        "unparseable",
        "no_plan",
    )
    episode.count_failures(result)
    assert dict(episode.failures) == {
        "precondition_violation": 1,
        "lack_of_3d_understanding": 1,
        "unparseable": 1,
        "no_plan": 1,
    }
