"""Test doubles for the search: tiny MDPs whose every number can be worked out by hand.

They implement the :class:`~stalm.search.search_mdp.SearchMDP` methods over their own small frozen
types (a named state, a named discrete action, an integer κ), which stand in for the real
``State``, ``DiscreteAction`` and ``Action``: the search only hashes and compares them. The
``cast`` helpers below are the one place the stand-ins are passed off as the real types.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from stalm.domain.actions import DiscreteAction
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.domain.params import Action
from stalm.search.concretize import TaskPlan
from stalm.search.search_mdp import SearchMDP
from stalm.world.state import State

INFEASIBLE_REWARD = -6.0


@dataclass(frozen=True, order=True)
class Node:
    """A synthetic state: just a name."""

    name: str

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, order=True)
class Move:
    """A synthetic discrete action: just a name."""

    name: str

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, order=True)
class Drawn:
    """A synthetic sampled action α(δ, κ): the discrete action and an integer κ."""

    discrete: Move
    kappa: int

    def __str__(self) -> str:
        return f"{self.discrete}#{self.kappa}"


@dataclass(frozen=True)
class Option:
    """One κ ψ may draw for an edge: where it leads (None: this draw is infeasible) and R."""

    kappa: int
    target: str | None
    reward: float = 0.0


def state(name: str) -> State:
    """A synthetic state typed as the real one."""
    return cast(State, Node(name))


def move(name: str) -> DiscreteAction:
    """A synthetic discrete action typed as the real one."""
    return cast(DiscreteAction, Move(name))


def drawn(action: str, kappa: int) -> Action:
    """A synthetic sampled action typed as the real one."""
    return cast(Action, Drawn(Move(action), kappa))


def plan(*names: str) -> TaskPlan:
    """A task plan of synthetic discrete actions."""
    return TaskPlan(tuple(move(name) for name in names))


def describe(value: object) -> str:
    """Short names for golden files (``str`` of the stand-ins, the kind for failures)."""
    if isinstance(value, Infeasibility):
        return f"infeasible({value.kind}: {value.detail})"
    return str(value)


@dataclass
class GraphMDP:
    """An MDP given as a table: (state, action) -> the κ options ψ draws from uniformly.

    A state's legal actions are the actions listed for it (in the order given); any other
    action has a false precondition. An option with ``target=None`` is an infeasible draw; an
    action with no options has no κ at all. ``calls`` counts every ψ and T call by kind, so
    tests can check what the search paid for.
    """

    edges: Mapping[tuple[str, str], tuple[Option, ...]]
    goal: frozenset[str] = frozenset()
    calls: Counter[str] = field(default_factory=Counter)

    def as_mdp(self) -> SearchMDP:
        """This double typed as the protocol."""
        return cast(SearchMDP, self)

    def legal_actions(self, state: Any) -> tuple[Any, ...]:
        return tuple(Move(a) for (s, a) in self.edges if s == state.name)

    def precondition_failure(self, state: Any, action: Any) -> str | None:
        if (state.name, action.name) in self.edges:
            return None
        return f"{action.name} is not applicable in {state.name}"

    def sample(self, state: Any, action: Any, rng: np.random.Generator) -> Any:
        self.calls["sample"] += 1
        why = self.precondition_failure(state, action)
        if why is not None:
            return Infeasibility("precondition", why)
        options = self.edges[(state.name, action.name)]
        if not options:
            return Infeasibility("no_placement", f"no kappa for {action.name} in {state.name}")
        option = options[int(rng.integers(len(options)))]
        if option.target is None:
            return Infeasibility("no_ik", f"{action.name}#{option.kappa} in {state.name}")
        return Drawn(action, option.kappa)

    def _option(self, state: Any, action: Any) -> Option:
        for option in self.edges[(state.name, action.discrete.name)]:
            if option.kappa == action.kappa:
                return option
        raise KeyError(action)

    def step(self, state: Any, action: Any) -> Outcome:
        self.calls["step"] += 1
        option = self._option(state, action)
        assert option.target is not None
        nxt = Node(option.target)
        return Outcome(cast(State, nxt), option.reward, True, None, option.target in self.goal)

    def infeasible(self, state: Any, why: Infeasibility) -> Outcome:
        self.calls["infeasible"] += 1
        return Outcome(state, INFEASIBLE_REWARD, False, why, False)

    def sample_and_step(self, state: Any, action: Any, rng: np.random.Generator) -> Any:
        kappa = self.sample(state, action, rng)
        if isinstance(kappa, Infeasibility):
            return None, self.infeasible(state, kappa)
        return kappa, self.step(state, kappa)

    def is_goal(self, state: Any) -> bool:
        return bool(state.name in self.goal)


def graph(edges: Iterable[tuple[str, str, Iterable[Option]]], goal: Iterable[str] = ()) -> GraphMDP:
    """A :class:`GraphMDP` from (state, action, options) rows."""
    return GraphMDP({(s, a): tuple(options) for s, a, options in edges}, frozenset(goal))


def det(target: str | None, reward: float = 0.0) -> tuple[Option]:
    """The options of a deterministic edge: one κ (numbered 0) to ``target``."""
    return (Option(0, target, reward),)


def warm_chain() -> GraphMDP:
    """s0 -a-> s1 -b-> s2 -c-> s3 (goal), rewards 0, 3, 100, one κ per edge; plus the wrong
    actions w at s0 and x at s1, which ψ can never ground (always infeasible)."""
    return graph(
        [
            ("s0", "a", det("s1", 0.0)),
            ("s0", "w", det(None)),
            ("s1", "b", det("s2", 3.0)),
            ("s1", "x", det(None)),
            ("s2", "c", det("s3", 100.0)),
        ],
        goal=["s3"],
    )


def detour() -> GraphMDP:
    """The model's plan [a, b, c] fails at its 3rd step (c is never feasible); the way on is
    d. Distractors: u at s0 leads to t0, whose only move is infeasible; e at s1 loops back to
    s0; f at s2 leads to t0. a and d draw κ from two options (one of d's is infeasible)."""
    return graph(
        [
            ("s0", "a", (Option(0, "s1"), Option(1, "s1"))),
            ("s0", "u", det("t0")),
            ("t0", "z", det(None)),
            ("s1", "b", det("s2", 3.0)),
            ("s1", "e", det("s0")),
            ("s2", "c", det(None)),
            ("s2", "d", (Option(0, "s3", 100.0), Option(1, None))),
            ("s2", "f", det("t0")),
        ],
        goal=["s3"],
    )


@dataclass
class FreshKappaMDP:
    """One state s0 with one action a whose every ψ draw is a new κ (numbered in order), all
    leading to s1 with reward 0 — to watch progressive widening without duplicate draws."""

    draws: int = 0

    def as_mdp(self) -> SearchMDP:
        return cast(SearchMDP, self)

    def legal_actions(self, state: Any) -> tuple[Any, ...]:
        return (Move("a"),) if state.name == "s0" else ()

    def precondition_failure(self, state: Any, action: Any) -> str | None:
        return None if state.name == "s0" and action == Move("a") else "not applicable"

    def sample(self, state: Any, action: Any, rng: np.random.Generator) -> Any:
        self.draws += 1
        return Drawn(action, self.draws)

    def step(self, state: Any, action: Any) -> Outcome:
        return Outcome(cast(State, Node("s1")), 0.0, True, None, False)

    def infeasible(self, state: Any, why: Infeasibility) -> Outcome:
        return Outcome(state, INFEASIBLE_REWARD, False, why, False)

    def sample_and_step(self, state: Any, action: Any, rng: np.random.Generator) -> Any:
        kappa = self.sample(state, action, rng)
        return kappa, self.step(state, kappa)

    def is_goal(self, state: Any) -> bool:
        return False


def replay(mdp: GraphMDP, start: str, actions: Iterable[Action]) -> Outcome:
    """Apply ``actions`` from ``start`` with T and return the last outcome (all must be
    feasible) — checks that a returned plan really reaches the goal."""
    current = state(start)
    outcome: Outcome | None = None
    for action in actions:
        outcome = mdp.step(current, action)
        assert outcome.feasible
        current = outcome.state
    assert outcome is not None
    return outcome
