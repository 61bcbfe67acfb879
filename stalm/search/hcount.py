"""The Hcount heuristic of Appendix C (Kim et al., 2022, as modified by the paper).

Hcount = |M| - |O_InGoal| + 1[o_target in O_InGoal] - 1[o_target not in O_InGoal and
o_target in O_goal], where M holds the objects (and doors) that occlude picking or placing a
goal object not yet at its goal, and recursively what occludes picking those. As a node value
for UCT: Q = 3 n(O_goal) - 3 Hcount. Its occlusions come from the geometric predicates, which
must be computed at every leaf the search evaluates: the cost the paper blames for
UCT-with-Hcount's time-outs. :class:`HcountLeafValue` pays it the way STaLM pays for its
queries (Appendix A): each leaf's predicates are brought forward from its parent's through the
action between them, not computed from scratch.

``o_target`` is the object of the action that led into the node (its arrival edge: PICK(o)
and PLACE(o, ...) act on o; OPEN on a door, no object), and whether it is "in O_InGoal" is
judged on the state that action acted on. So picking an object up that already sat at its
goal costs +1 (the penalty that traps UCT-with-Hcount in P5/P6, §4.3), and picking or placing
a goal object that was not at its goal earns -1. A node reached by no known edge (a search
root) has no o_target and neither term applies. (The held object cannot stand in for
o_target: it has no pose, so it is never "in goal" and the +1 would never fire.)
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable

import numpy as np

from stalm.domain.actions import Open
from stalm.predicates.engine import PredicateCache, PredicateEngine
from stalm.predicates.literals import GroundLiteral
from stalm.predicates.memo import PredicateMemo
from stalm.search import LeafValue
from stalm.search.search_mdp import SearchMDP
from stalm.search.tree import Edge
from stalm.world.problem import Problem
from stalm.world.relations import at_position
from stalm.world.state import State


def objects_in_goal(problem: Problem, state: State) -> set[str]:
    """Goal objects all of whose goal conjuncts hold."""
    spec = problem.spec
    by_object: dict[str, bool] = {}
    for g in problem.goal:
        holds = at_position(spec, state, g.obj, g.direction, g.ref)
        by_object[g.obj] = by_object.get(g.obj, True) and holds
    return {obj for obj, holds in by_object.items() if holds}


def occluder_set(problem: Problem, literals: Iterable[GroundLiteral], state: State) -> set[str]:
    """M: occluders of the goal objects not yet at their goal, closed under pick occlusion."""
    picks: dict[str, set[str]] = defaultdict(set)
    places: dict[tuple[str, str, str], set[str]] = defaultdict(set)
    for literal in literals:
        if literal.name == "PickOccludedBy":
            picks[literal.args[0]].add(literal.args[1])
        elif literal.name == "PlaceOccludedBy":
            obj, direction, ref, occluder = literal.args
            places[(obj, direction, ref)].add(occluder)
    done = objects_in_goal(problem, state)
    occluders: set[str] = set()
    for g in problem.goal:
        if g.obj in done:
            continue
        occluders |= picks[g.obj] | places[(g.obj, g.direction, g.ref)]
    frontier = list(occluders)
    while frontier:
        for blocker in picks[frontier.pop()]:
            if blocker not in occluders:
                occluders.add(blocker)
                frontier.append(blocker)
    return occluders


def target_term(problem: Problem, arrival: Edge | None) -> int:
    """Appendix C's o_target terms: +1 if o_target was in O_InGoal, -1 if it was a goal object
    not in O_InGoal, judged on the state the arrival action acted on; 0 without an arrival or
    when the action moved no object (OPEN)."""
    if arrival is None or isinstance(arrival.action, Open):
        return 0
    target = arrival.action.obj
    if target in objects_in_goal(problem, arrival.state):
        return 1
    if target in {g.obj for g in problem.goal}:
        return -1
    return 0


def hcount(
    problem: Problem,
    literals: Iterable[GroundLiteral],
    state: State,
    arrival: Edge | None = None,
) -> int:
    """Appendix C's cost-to-go estimate for ``state`` with predicates ``literals``, reached by
    ``arrival`` (the edge whose action names o_target; None: no o_target)."""
    done = objects_in_goal(problem, state)
    value = len(occluder_set(problem, literals, state)) - len(done)
    return value + target_term(problem, arrival)


def hcount_value(
    problem: Problem,
    literals: Iterable[GroundLiteral],
    state: State,
    arrival: Edge | None = None,
) -> float:
    """Q = 3 n(O_goal) - 3 Hcount (Appendix C)."""
    goal_objects = {g.obj for g in problem.goal}
    return 3.0 * len(goal_objects) - 3.0 * hcount(problem, literals, state, arrival)


class HcountLeafValue:
    """UCT-with-Hcount's leaf value: ``hcount_value`` of the leaf's predicates.

    A leaf's predicates come from the trial's :class:`PredicateMemo`, derived from its
    parent's with :meth:`PredicateEngine.update` along the edge the search took into it
    (equal to computing them from scratch, and several times cheaper); only a state reached
    by no known edge, such as a search root, is computed from scratch. The memo keeps them for
    the whole trial, since the trees of later real steps revisit the states of earlier ones.
    The value also reads ``arrival`` for o_target (:func:`target_term`). Deterministic: it
    never depends on the generator. ``computed_from_scratch`` and ``brought_forward`` count
    the computations the leaves caused.
    """

    def __init__(self, problem: Problem, predicates: PredicateMemo | PredicateEngine) -> None:
        self.problem = problem
        self.memo = (
            predicates if isinstance(predicates, PredicateMemo) else PredicateMemo(predicates)
        )
        self.computed_from_scratch = 0
        self.brought_forward = 0

    def __call__(
        self,
        mdp: SearchMDP,
        state: State,
        depth: int,
        rng: np.random.Generator,
        arrival: Edge | None = None,
    ) -> LeafValue:
        literals = self.predicates(state, arrival).literals
        return LeafValue(hcount_value(self.problem, literals, state, arrival))

    def predicates(self, state: State, arrival: Edge | None = None) -> PredicateCache:
        """The predicates of ``state``, from its parent's if ``arrival`` leads into it."""
        memo = self.memo
        scratch, forward = memo.computed_from_scratch, memo.brought_forward
        parent, action = (None, None) if arrival is None else (arrival.state, arrival.action)
        cache = memo.of(state, parent, action)
        self.computed_from_scratch += memo.computed_from_scratch - scratch
        self.brought_forward += memo.brought_forward - forward
        return cache
