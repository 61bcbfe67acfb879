"""The movable objects the symbolic task keeps: those an action on which can matter."""

from __future__ import annotations

from stalm.domain.vocabulary import Vocabulary
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.fast_downward import SymbolicProposer
from stalm.proposers.protocol import ProposalRequest
from stalm.proposers.task_objects import task_objects


def lit(name: str, *args: str) -> GroundLiteral:
    return GroundLiteral(name, args)


VOCABULARY = Vocabulary(
    movables=("can", "blocker", "held", "clutter", "crowd", "reference", "waited"),
    regions=("table", "counter", "shelf"),
    doors=("door",),
)


def test_an_object_the_abstraction_only_places_is_left_out_with_its_literals() -> None:
    init = [
        lit("AtPosition", "can", "on", "table"),
        lit("AtPosition", "blocker", "on", "table"),
        lit("AtPosition", "clutter", "on", "table"),
        lit("AtPosition", "clutter", "left_of", "blocker"),  # relative to a kept object
        lit("AtPosition", "crowd", "on", "shelf"),
        lit("AtPosition", "reference", "on", "counter"),
        lit("AtPosition", "waited", "on", "counter"),
        lit("PickOccludedBy", "can", "blocker"),
        lit("PickOccludedBy", "blocker", "door"),
        lit("RobotHolding", "held"),
        lit("Needs", "failure0", "waited"),
        lit("IsClosed", "door"),
    ]
    goal = [lit("AtPosition", "can", "left_of", "reference")]
    kept, literals = task_objects(VOCABULARY, init, goal)
    assert kept.movables == ("can", "blocker", "held", "reference", "waited")
    assert kept.regions == VOCABULARY.regions and kept.doors == VOCABULARY.doors
    left_out = {"clutter", "crowd"}
    assert literals == [x for x in init if not left_out & set(x.args)]


def test_what_stands_on_a_region_a_failure_names_is_kept() -> None:
    """Picking it changes the region, which lifts the failed placement recorded there: the
    way a plan makes room on a crowded region."""
    init = [
        lit("AtPosition", "can", "on", "table"),
        lit("AtPosition", "crowd", "on", "shelf"),
        lit("AtPosition", "clutter", "on", "counter"),
        lit("PlaceFailed", "can", "on", "shelf", "shelf"),
    ]
    goal = [lit("AtPosition", "can", "on", "shelf")]
    kept, literals = task_objects(VOCABULARY, init, goal)
    assert kept.movables == ("can", "crowd")
    assert literals == init[:2] + init[3:]


def test_the_proposer_plans_alike_without_an_object_that_cannot_matter(
    problems, initial_literals
) -> None:
    """P2 with what the predicates say about bottle2 beyond where it stands taken out: the
    proposer leaves bottle2 out of Fast Downward's task and finds the same plans."""
    problem = problems["P2"]
    literals = {
        x for x in initial_literals("P2") if "bottle2" not in x.args or x.name == "AtPosition"
    }
    vocabulary = Vocabulary.from_problem(problem)
    kept, _ = task_objects(vocabulary, literals, [])
    assert "bottle2" in vocabulary.movables and "bottle2" not in kept.movables
    plain = SymbolicProposer(needed_objects_only=False).propose(
        ProposalRequest(problem, problem.initial_state, frozenset(literals), 3, seed=0)
    )
    needed = SymbolicProposer().propose(
        ProposalRequest(problem, problem.initial_state, frozenset(literals), 3, seed=0)
    )
    assert needed.plans and needed.plans == plain.plans
    assert all("bottle2" not in str(plan) for plan in needed.plans)


def test_no_object_is_left_out_where_any_relative_placement_is_grounded(
    problems, initial_literals, monkeypatch
) -> None:
    """With ``goal_relations_only`` off, a relative PLACE next to any object is an action of
    its own, which leaving the object out would lose: the proposer keeps every object."""
    import stalm.proposers.fast_downward as fast_downward

    def pruning_not_expected(*args: object) -> None:
        raise AssertionError("objects left out while every relative placement is grounded")

    monkeypatch.setattr(fast_downward, "task_objects", pruning_not_expected)
    problem = problems["P2"]
    proposer = SymbolicProposer(goal_relations_only=False)
    proposal = proposer.propose(
        ProposalRequest(
            problem, problem.initial_state, frozenset(initial_literals("P2")), 1, seed=0
        )
    )
    assert proposal.plans
