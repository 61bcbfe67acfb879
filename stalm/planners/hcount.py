"""The Hcount heuristic of Appendix C (Kim et al., 2022, as modified by the paper).

Hcount = |M| - |O_InGoal| + 1[o_target in O_InGoal] - 1[o_target not in O_InGoal and
o_target in O_goal], where M holds the objects (and doors) that occlude picking or placing a
goal object not yet at its goal, and recursively what occludes picking those. As a node value
for UCT: Q = 3 n(O_goal) - 3 Hcount. Its occlusions come from the geometric predicates, which
must be computed at every leaf the search evaluates: the cost the paper blames for
UCT-with-Hcount's time-outs.

``o_target`` is the object the action into the node moved; a State records only what is in
the hand, so the held object stands in for it (None after a PLACE).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable

from stalm.predicates.literals import GroundLiteral
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
