"""The Hcount heuristic of Appendix C (Kim et al., 2022, as modified by the paper).

Hcount = |M| - |O_InGoal| + 1[o_target in O_InGoal] - 1[o_target not in O_InGoal and
o_target in O_goal], where M holds the objects (and doors) that occlude picking or placing a
goal object not yet at its goal, and recursively what occludes picking those. As a node value
for UCT: Q = 3 n(O_goal) - 3 Hcount. Its occlusions come from the geometric predicates, which
must be computed at every leaf the search evaluates: the cost the paper blames for
UCT-with-Hcount's time-outs. :class:`HcountLeafValue` pays it the way STaLM pays for its
queries (Appendix A): each leaf's predicates are brought forward from its parent's through the
action between them, not computed from scratch.

``o_target`` is the object the action into the node moved; a State records only what is in
the hand, so the held object stands in for it (None after a PLACE).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable

import numpy as np

from stalm.predicates.engine import PredicateCache, PredicateEngine
from stalm.predicates.literals import GroundLiteral
from stalm.search import LeafValue
from stalm.search.mdp import SearchMDP
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


def hcount(problem: Problem, literals: Iterable[GroundLiteral], state: State) -> int:
    """Appendix C's cost-to-go estimate for ``state`` with predicates ``literals``."""
    goal_objects = {g.obj for g in problem.goal}
    done = objects_in_goal(problem, state)
    target = state.held.obj if state.held is not None else None
    value = len(occluder_set(problem, literals, state)) - len(done)
    if target is not None and target in done:
        value += 1
    if target is not None and target not in done and target in goal_objects:
        value -= 1
    return value


def hcount_value(problem: Problem, literals: Iterable[GroundLiteral], state: State) -> float:
    """Q = 3 n(O_goal) - 3 Hcount (Appendix C)."""
    goal_objects = {g.obj for g in problem.goal}
    return 3.0 * len(goal_objects) - 3.0 * hcount(problem, literals, state)


class HcountLeafValue:
    """UCT-with-Hcount's leaf value: ``hcount_value`` of the leaf's predicates.

    A leaf's predicates are derived from its parent's with :meth:`PredicateEngine.update`
    along the edge the search took into it (equal to computing them from scratch, and several
    times cheaper); only a state reached by no known edge, such as a search root, is computed
    from scratch. Predicates are kept per state for the whole trial, since the
    trees of later real steps revisit the states of earlier ones. Deterministic: the value of a
    state never depends on the generator.
    """

    def __init__(self, problem: Problem, engine: PredicateEngine) -> None:
        self.problem = problem
        self.engine = engine
        self._predicates: dict[State, PredicateCache] = {}
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
        return LeafValue(hcount_value(self.problem, literals, state))

    def predicates(self, state: State, arrival: Edge | None = None) -> PredicateCache:
        """The predicates of ``state``, from its parent's if ``arrival`` leads into it."""
        known = self._predicates.get(state)
        if known is not None:
            return known
        if arrival is None:
            cache = self.engine.compute(state)
            self.computed_from_scratch += 1
        else:
            parent = self.predicates(arrival.state)
            cache = self.engine.update(parent, arrival.action, state)
            self.brought_forward += 1
        self._predicates[state] = cache
        return cache
