"""The hybrid search tree of §3.3: discrete nodes T(s) and continuous nodes T(s_α(δ)).

Mechanics only: this module stores statistics and backs returns up. Apart from asking for the
root's legal actions in :meth:`SearchTree.for_root` it never calls the MDP, and it never
chooses: which child to follow, when to widen and how to value a leaf are policies
(:mod:`stalm.search.policies`), so baselines swap them without touching the tree.

Shape (the paper's T(s), with this implementation's choices where it is silent):

* Discrete nodes are keyed by :class:`State`, so identical states reached along different
  paths are one node (the paper's T(s)); ``n`` counts the visits that passed through it.
* A discrete node has one continuous node per discrete action α(δ). All legal actions are
  registered when the node is created (n = 0, Q = 0); a warm-start plan may add an illegal
  one, because the model's mistake is worth remembering as a -6 branch.
* A continuous node has ``n``, ``Q`` = Q(s, α(δ)) and one child per distinct κ draw, keyed by
  the sampled :class:`Action` or the :class:`Infeasibility` ψ returned. A κ child keeps its
  ``n``, ``Q`` = Q(s, α(δ, κ)) and the :class:`Outcome` of T (next state, reward, feasible,
  goal), so T is paid once per child. The next state's own node, if it has one, is found by
  state, not stored as a pointer.
* Q values are incremental means of discounted returns, per child (the paper's line 22
  divides by the parent's count, which only gives a mean when the parent has one child).
* Terminal arrivals (infeasible, goal, horizon) create no discrete node: an infeasible
  outcome's s' = s is the absorbing failure, not a revisit of s, and a goal or horizon state is
  never expanded from that arrival.

Mutation goes through :class:`SearchTree` methods; readers get frozen views.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from stalm.domain.actions import DiscreteAction
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.search.search_mdp import SearchMDP
from stalm.search.transition import Kappa
from stalm.world.state import State

# ------------------------------------------------------------------------------ read-only views


@dataclass(frozen=True)
class ChildStats:
    """What a selection policy sees at one decision: the children of one node, in order.

    ``keys`` are discrete actions (at a discrete node) or κ keys (at a continuous node);
    ``parent_visits`` is the node's visit count before the current simulation.
    """

    state: State
    keys: tuple[Any, ...]
    q: tuple[float, ...]
    n: tuple[int, ...]
    parent_visits: int


@dataclass(frozen=True)
class KappaView:
    """One κ child: its key, visits, mean return and the stored outcome of T."""

    kappa: Kappa
    n: int
    q: float
    outcome: Outcome


@dataclass(frozen=True)
class ContinuousNodeView:
    """T(s_α(δ)): visits, Q(s, α(δ)) and the κ children in insertion order."""

    action: DiscreteAction
    n: int
    q: float
    children: tuple[KappaView, ...]

    def child(self, kappa: Kappa) -> KappaView:
        for view in self.children:
            if view.kappa == kappa:
                return view
        raise KeyError(kappa)


@dataclass(frozen=True)
class DiscreteNodeView:
    """T(s): visits and the continuous children in registration order."""

    state: State
    n: int
    children: tuple[ContinuousNodeView, ...]

    def child(self, action: DiscreteAction) -> ContinuousNodeView:
        for view in self.children:
            if view.action == action:
                return view
        raise KeyError(action)


@dataclass(frozen=True)
class TreeStats:
    """Sizes of a tree, for results and logs."""

    discrete_nodes: int
    continuous_nodes: int
    kappa_children: int
    infeasible_children: int
    root_visits: int


@dataclass(frozen=True)
class Edge:
    """One step of a path through the tree: from ``state`` by ``action`` with ``kappa``."""

    state: State
    action: DiscreteAction
    kappa: Kappa


# ------------------------------------------------------------------------------ mutable nodes


@dataclass(slots=True)
class _KappaChild:
    outcome: Outcome
    n: int = 0
    q: float = 0.0


@dataclass(slots=True)
class _ContinuousNode:
    n: int = 0
    q: float = 0.0
    children: dict[Kappa, _KappaChild] = field(default_factory=dict)


@dataclass(slots=True)
class _DiscreteNode:
    n: int = 0
    children: dict[DiscreteAction, _ContinuousNode] = field(default_factory=dict)


class SearchTree:
    """Discrete nodes by state, with their continuous nodes and κ children.

    Create it with the root state and the root's legal actions (:meth:`for_root` asks an MDP
    for them). Nodes and children are only ever added, never removed (:meth:`subtree` makes a
    new tree of what a new root still reaches), and statistics change only in :meth:`backup`.
    """

    def __init__(self, root: State, root_actions: Sequence[DiscreteAction]) -> None:
        self._root = root
        self._nodes: dict[State, _DiscreteNode] = {}
        self.add_node(root, root_actions)

    @staticmethod
    def for_root(mdp: SearchMDP, root: State) -> SearchTree:
        """A tree holding only the root, with every legal action registered."""
        return SearchTree(root, mdp.legal_actions(root))

    # ---------------------------------------------------------------- structure
    @property
    def root(self) -> State:
        return self._root

    def __contains__(self, state: object) -> bool:
        return state in self._nodes

    def __len__(self) -> int:
        return len(self._nodes)

    def states(self) -> Iterator[State]:
        """Discrete-node states in creation order."""
        return iter(self._nodes)

    def add_node(self, state: State, actions: Sequence[DiscreteAction]) -> bool:
        """Create T(s) with a continuous node per action; False (and no change) if it exists."""
        if state in self._nodes:
            return False
        self._nodes[state] = _DiscreteNode(
            children={action: _ContinuousNode() for action in actions}
        )
        return True

    def add_action(self, state: State, action: DiscreteAction) -> bool:
        """Register ``action`` at T(s) even if it is not legal; False if already there."""
        node = self._nodes[state]
        if action in node.children:
            return False
        node.children[action] = _ContinuousNode()
        return True

    def add_kappa(
        self, state: State, action: DiscreteAction, kappa: Kappa, outcome: Outcome
    ) -> bool:
        """Add the κ child with T's outcome; False (the draw is dropped) if it exists."""
        node = self._nodes[state].children[action]
        if kappa in node.children:
            return False
        node.children[kappa] = _KappaChild(outcome)
        return True

    def subtree(self, root: State) -> SearchTree:
        """The part of this tree reachable from ``root``, as a new tree rooted there.

        Tree reuse between real steps, as the authors' code does: after the
        robot executes an action, the node its outcome leads to becomes the next search's
        root and keeps every statistic below it (visits, Q, κ children and their stored
        outcomes); nodes no longer reachable are dropped, so the tree's memory follows what
        can still matter. Reachable means through a feasible κ child whose next state has a
        node. The nodes are shared, not copied: this tree must not be used afterwards.
        """
        if root not in self._nodes:
            raise KeyError("the new root has no node in this tree")
        kept: dict[State, _DiscreteNode] = {}
        frontier = [root]
        while frontier:
            state = frontier.pop()
            if state in kept:
                continue
            node = self._nodes[state]
            kept[state] = node
            for cont in node.children.values():
                for child in cont.children.values():
                    following = child.outcome.state
                    if child.outcome.feasible and following in self._nodes:
                        frontier.append(following)
        tree = SearchTree.__new__(SearchTree)
        tree._root = root
        # creation order is kept, so snapshots and iteration stay deterministic
        tree._nodes = {state: node for state, node in self._nodes.items() if state in kept}
        return tree

    # ---------------------------------------------------------------- reading
    def outcome(self, edge: Edge) -> Outcome:
        return self._nodes[edge.state].children[edge.action].children[edge.kappa].outcome

    def has_kappa(self, state: State, action: DiscreteAction, kappa: Kappa) -> bool:
        return kappa in self._nodes[state].children[action].children

    def visits(self, state: State) -> int:
        return self._nodes[state].n

    def action_visits(self, state: State, action: DiscreteAction) -> int:
        return self._nodes[state].children[action].n

    def num_kappas(self, state: State, action: DiscreteAction) -> int:
        return len(self._nodes[state].children[action].children)

    def action_stats(self, state: State) -> ChildStats:
        """The discrete-action choice at T(s), for a selection policy."""
        node = self._nodes[state]
        children = node.children
        return ChildStats(
            state=state,
            keys=tuple(children),
            q=tuple(child.q for child in children.values()),
            n=tuple(child.n for child in children.values()),
            parent_visits=node.n,
        )

    def kappa_stats(self, state: State, action: DiscreteAction) -> ChildStats:
        """The κ choice at T(s_α(δ)), for a selection policy."""
        node = self._nodes[state].children[action]
        children = node.children
        return ChildStats(
            state=state,
            keys=tuple(children),
            q=tuple(child.q for child in children.values()),
            n=tuple(child.n for child in children.values()),
            parent_visits=node.n,
        )

    def node(self, state: State) -> DiscreteNodeView:
        """A frozen copy of T(s) and its subtree of continuous nodes and κ children."""
        node = self._nodes[state]
        return DiscreteNodeView(
            state=state,
            n=node.n,
            children=tuple(
                ContinuousNodeView(
                    action=action,
                    n=cont.n,
                    q=cont.q,
                    children=tuple(
                        KappaView(kappa=kappa, n=child.n, q=child.q, outcome=child.outcome)
                        for kappa, child in cont.children.items()
                    ),
                )
                for action, cont in node.children.items()
            ),
        )

    def stats(self) -> TreeStats:
        continuous = 0
        kappas = 0
        infeasible = 0
        for node in self._nodes.values():
            continuous += len(node.children)
            for cont in node.children.values():
                kappas += len(cont.children)
                infeasible += sum(not child.outcome.feasible for child in cont.children.values())
        return TreeStats(
            discrete_nodes=len(self._nodes),
            continuous_nodes=continuous,
            kappa_children=kappas,
            infeasible_children=infeasible,
            root_visits=self._nodes[self._root].n,
        )

    # ---------------------------------------------------------------- backup
    def backup(
        self,
        path: Sequence[Edge],
        tail_value: float,
        gamma: float,
        leaf: State | None = None,
    ) -> tuple[float, ...]:
        """Back one simulation's returns up ``path``; return the return at each edge.

        The return after the last edge is ``tail_value`` (0 for a terminal arrival, the leaf
        estimate otherwise); going up, G = r + γ·G. Every κ child and continuous node on the
        path gets one visit and moves its Q to the incremental mean; every discrete node the
        path leaves from gets one visit, and so does ``leaf``, the node the simulation ended in
        (None after a terminal arrival). Edges are applied in order, so a state visited twice
        on one path is counted twice.
        """
        returns: list[float] = []
        value = tail_value
        for edge in reversed(path):
            node = self._nodes[edge.state]
            cont = node.children[edge.action]
            child = cont.children[edge.kappa]
            value = child.outcome.reward + gamma * value
            returns.append(value)
            child.n += 1
            child.q += (value - child.q) / child.n
            cont.n += 1
            cont.q += (value - cont.q) / cont.n
            node.n += 1
        if leaf is not None:
            self._nodes[leaf].n += 1
        returns.reverse()
        return tuple(returns)

    # ---------------------------------------------------------------- golden files
    def snapshot(self, describe: Callable[[object], str] = repr) -> dict[str, Any]:
        """The whole tree as JSON-able data (nodes in creation order), for golden files.

        ``describe`` names states, actions and κ keys; Q values are rounded to 9 decimals so
        a golden file does not change with the last bits of floating point.
        """
        nodes = []
        for state, node in self._nodes.items():
            actions = []
            for action, cont in node.children.items():
                kappas = [
                    {
                        "kappa": describe(kappa),
                        "n": child.n,
                        "q": round(child.q, 9),
                        "reward": child.outcome.reward,
                        "feasible": child.outcome.feasible,
                        "goal": child.outcome.goal_reached,
                        "next": describe(child.outcome.state),
                        "failure": _failure_kind(child.outcome.failure),
                    }
                    for kappa, child in cont.children.items()
                ]
                actions.append(
                    {
                        "action": describe(action),
                        "n": cont.n,
                        "q": round(cont.q, 9),
                        "kappas": kappas,
                    }
                )
            nodes.append({"state": describe(state), "n": node.n, "actions": actions})
        return {"root": describe(self._root), "nodes": nodes}


def _failure_kind(failure: Infeasibility | None) -> str | None:
    return None if failure is None else failure.kind
