"""Cycles of pick occlusions, set aside by the symbolic proposer when they leave no plan."""

from __future__ import annotations

from stalm.predicates.literals import GroundLiteral
from stalm.proposers.fast_downward import SymbolicProposer
from stalm.proposers.occlusion_cycles import occlusion_cycles, without_occlusion_cycles
from stalm.proposers.protocol import ProposalRequest


def pick(subject: str, occluder: str) -> GroundLiteral:
    return GroundLiteral("PickOccludedBy", (subject, occluder))


def test_only_the_pick_occlusions_on_a_cycle_are_set_aside() -> None:
    literals = {
        # a three-cycle, with `goal` hanging behind it and a door in front of one member
        pick("a", "b"),
        pick("b", "c"),
        pick("c", "a"),
        pick("c", "door"),
        pick("goal", "a"),
        # a two-cycle, and a chain that is not one
        pick("x", "y"),
        pick("y", "x"),
        pick("p", "q"),
        pick("q", "r"),
        GroundLiteral("PlaceOccludedBy", ("goal", "on", "table", "a")),
        GroundLiteral("CannotPick", ("r",)),
        GroundLiteral("IsClosed", ("door",)),
    }
    cycles = {pick("a", "b"), pick("b", "c"), pick("c", "a"), pick("x", "y"), pick("y", "x")}
    assert occlusion_cycles(literals) == cycles
    kept, aside = without_occlusion_cycles(literals)
    assert aside == cycles and kept == literals - cycles


def test_without_a_cycle_nothing_is_set_aside() -> None:
    literals = {pick("a", "b"), pick("b", "door"), GroundLiteral("IsClosed", ("door",))}
    assert without_occlusion_cycles(literals) == (frozenset(literals), frozenset())


def test_a_cycle_that_leaves_no_plan_is_planned_without(problems, initial_literals) -> None:
    """P2 with bottle2's pick occluded by the salter, whose pick bottle2 occludes: the goal
    (the salter right of bottle1) is unreachable in the abstraction, and reachable once the
    two claims are set aside; the proposal names them."""
    problem = problems["P2"]
    literals = set(initial_literals("P2"))
    assert pick("salter", "bottle2") in literals
    literals.add(pick("bottle2", "salter"))
    cycle = (str(pick("bottle2", "salter")), str(pick("salter", "bottle2")))

    strict = SymbolicProposer(break_occlusion_cycles=False).propose(
        ProposalRequest(problem, problem.initial_state, frozenset(literals), 2, seed=0)
    )
    assert not strict.plans and not strict.set_aside
    assert strict.no_plan == ("the predicate abstraction of this state has no plan to the goal",)

    relaxed = SymbolicProposer().propose(
        ProposalRequest(problem, problem.initial_state, frozenset(literals), 2, seed=0)
    )
    assert relaxed.plans and not relaxed.no_plan
    assert relaxed.set_aside == cycle
    assert all(str(plan[-1]) == "place(salter, right_of, bottle1)" for plan in relaxed.plans)


def test_a_plan_found_with_every_literal_sets_nothing_aside(problems, initial_literals) -> None:
    """A cycle no plan needs broken (bottle1, the goal's reference, stays where it is) is
    kept: the proposer relaxes nothing while the abstraction has a plan."""
    problem = problems["P2"]
    literals = set(initial_literals("P2")) | {pick("bottle1", "bottle1")}
    proposal = SymbolicProposer().propose(
        ProposalRequest(problem, problem.initial_state, frozenset(literals), 1, seed=0)
    )
    assert proposal.plans and proposal.set_aside == ()
