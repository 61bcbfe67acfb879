"""Goals that no placement can make true together: contradictory or cyclic conjuncts.

A goal is a conjunction of AtPosition atoms, and some conjunctions are impossible whatever the
scene: one object on two regions; two objects related by a direction but put on different
regions (a relative direction holds only between objects resting on one region); one pair in
two directions (the larger offset decides the one direction a pair has,
:func:`~stalm.world.relations.direction_between`); or directions that go round in a cycle
(``a`` left of ``b``, ``b`` left of ``c``, ``c`` left of ``a``: each says one offset along the
region's side-to-side axis is positive, and they cannot all be). A planner given such a goal
can only spend its budget, so the problem file is refused when it is loaded, naming the goals.

Judged on names alone (no geometry), with ``x right_of y`` read as ``y left_of x`` and
``x front_of y`` as ``y behind_of x``.
"""

from __future__ import annotations

from collections.abc import Sequence

Goal = tuple[str, str, str]
"""(object, direction, reference) of one AtPosition atom."""

AXES: dict[str, tuple[str, bool]] = {
    "left_of": ("side", False),
    "right_of": ("side", True),
    "behind_of": ("depth", False),
    "front_of": ("depth", True),
}
"""Each relative direction as an axis of the region's view and whether it reads the pair
backwards: ``x left_of y`` puts x farther along the side axis than y, ``x right_of y`` puts y
farther."""


SHOWN = 6
"""Goals of a cycle named in its message at most (the rest are counted)."""


def _said(goal: Goal) -> str:
    obj, direction, ref = goal
    return f"'{obj}' {direction} '{ref}'"


def goal_contradiction(goals: Sequence[Goal]) -> str | None:
    """Why no state satisfies every goal of ``goals`` (one line naming them by index, as a
    problem file's ``goal[i]``), or None when the names allow it."""
    return (
        _two_regions(goals)
        or _two_directions(goals)
        or _regions_of_relations(goals)
        or _cycle(goals)
    )


def _two_regions(goals: Sequence[Goal]) -> str | None:
    where: dict[str, int] = {}
    for index, (obj, direction, ref) in enumerate(goals):
        if direction != "on":
            continue
        first = where.setdefault(obj, index)
        if goals[first][2] != ref:
            return (
                f"goal[{index}]: {_said(goals[index])} contradicts goal[{first}] "
                f"({_said(goals[first])}): an object rests on one region"
            )
    return None


def _edges(goals: Sequence[Goal]) -> list[tuple[str, str, str, int]]:
    """(axis, farther object, nearer object, goal index) of every relative goal."""
    edges = []
    for index, (obj, direction, ref) in enumerate(goals):
        if direction in AXES:
            axis, backwards = AXES[direction]
            edges.append((axis, ref, obj, index) if backwards else (axis, obj, ref, index))
    return edges


def _two_directions(goals: Sequence[Goal]) -> str | None:
    """One pair related along both axes (``a`` left of ``b`` and ``a`` behind ``b``)."""
    seen: dict[frozenset[str], tuple[str, int]] = {}
    for axis, farther, nearer, index in _edges(goals):
        pair = frozenset((farther, nearer))
        first_axis, first = seen.setdefault(pair, (axis, index))
        if first_axis != axis:
            return (
                f"goal[{index}]: {_said(goals[index])} contradicts goal[{first}] "
                f"({_said(goals[first])}): a pair of objects stands in one direction, the "
                "one of the larger offset"
            )
    return None


def _regions_of_relations(goals: Sequence[Goal]) -> str | None:
    """Objects tied by relative goals (directly or through others) put on two regions."""
    parent: dict[str, str] = {}

    def root(name: str) -> str:
        while parent.get(name, name) != name:
            name = parent[name]
        return name

    for _, farther, nearer, _ in _edges(goals):
        parent[root(farther)] = root(nearer)
    placed: dict[str, int] = {}
    for index, (obj, direction, _) in enumerate(goals):
        if direction != "on":
            continue
        first = placed.setdefault(root(obj), index)
        if goals[first][2] != goals[index][2]:
            return (
                f"goal[{index}]: {_said(goals[index])} contradicts goal[{first}] "
                f"({_said(goals[first])}): the relative goals tie '{goals[index][0]}' to "
                f"'{goals[first][0]}', and a direction holds only between objects on one region"
            )
    return None


def _cycle(goals: Sequence[Goal]) -> str | None:
    """Directions along one axis that go round (``a`` left of ``b`` and ``b`` left of
    ``a``; or through more objects)."""
    for axis in ("side", "depth"):
        after: dict[str, list[tuple[str, int]]] = {}
        for edge_axis, farther, nearer, index in _edges(goals):
            if edge_axis == axis:
                after.setdefault(farther, []).append((nearer, index))
        found = _find_cycle(after)
        if found is not None:
            named = ", ".join(f"goal[{i}] ({_said(goals[i])})" for i in found[:SHOWN])
            more = f" and {len(found) - SHOWN} more" if len(found) > SHOWN else ""
            return f"{named}{more} go round in a cycle: no placement makes them all true"
    return None


def _find_cycle(after: dict[str, list[tuple[str, int]]]) -> list[int] | None:
    """The goal indices along one cycle of the graph ``after`` (node: [(next, goal)]), in
    order from the smallest index, or None; an iterative depth-first search."""
    state: dict[str, int] = {}  # 1: on the current path, 2: finished
    for start in sorted(after):
        if state.get(start):
            continue
        state[start] = 1
        stack = [(start, -1, iter(after[start]))]  # (node, goal that led to it, its edges)
        while stack:
            node, _, edges = stack[-1]
            step = next(edges, None)
            if step is None:
                state[node] = 2
                stack.pop()
                continue
            nxt, index = step
            if state.get(nxt) == 1:
                on_path = [entry[0] for entry in stack]
                ring = [entry[1] for entry in stack[on_path.index(nxt) + 1 :]] + [index]
                turn = ring.index(min(ring))
                return ring[turn:] + ring[:turn]
            if not state.get(nxt):
                state[nxt] = 1
                stack.append((nxt, index, iter(after.get(nxt, ()))))
    return None
