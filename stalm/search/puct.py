"""PUCT selection with a prior over discrete actions (the LLM-MCTS baseline, §4.2).

LLM-MCTS (Zhao et al., 2024) replaces UCT's exploration bonus at discrete nodes with PUCT
(Rosin, 2011): a child's bonus is proportional to a prior probability P(s, a), so actions the
prior favours are tried first and more often. The prior is *injected* (a :class:`PriorSource`)
so the search stays free of language models: the planner supplies one that asks a model, tests
supply one from a table. :func:`vote_prior` turns votes (e.g. the first actions of sampled
task plans) into such a distribution.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import Protocol, cast

import numpy as np

from stalm.domain.actions import DiscreteAction
from stalm.search.policies import argmax_random_tie
from stalm.search.tree import ChildStats
from stalm.world.state import State


class PriorSource(Protocol):
    """P(s, ·): one probability per action of ``actions`` (the node's legal actions, in the
    tree's order), non-negative and summing to 1."""

    def __call__(self, state: State, actions: tuple[DiscreteAction, ...]) -> np.ndarray: ...


@dataclass(frozen=True)
class PUCTSelection:
    """PUCT: Q + c·P(s, a)·sqrt(N_parent + 1) / (1 + N_child), exact ties broken with ``rng``.

    Q is the raw mean return, as in :class:`~stalm.search.policies.UCTSelection`, hence the
    same c = 50 (the authors' value for LLM-MCTS). N_parent counts the node's visits *before*
    the current simulation; the +1 (as UCT's ln(N_parent + 1)) keeps the bonus alive at a
    node's first selection, so that choice already follows the prior -- with the textbook
    sqrt(N_parent) every bonus would be 0 there and the first child tried would be a uniform
    draw whatever the model said. The prior is asked at every selection.
    """

    c: float
    prior: PriorSource

    def scores(self, stats: ChildStats) -> np.ndarray:
        q = np.asarray(stats.q, dtype=float)
        actions = cast(tuple[DiscreteAction, ...], stats.keys)
        prior = np.asarray(self.prior(stats.state, actions), dtype=float)
        if prior.shape != q.shape:
            raise ValueError(
                f"the prior has {prior.size} probabilities for {q.size} actions at {stats.state}"
            )
        n = np.asarray(stats.n, dtype=float)
        return q + self.c * prior * math.sqrt(stats.parent_visits + 1) / (1.0 + n)

    def __call__(self, stats: ChildStats, rng: np.random.Generator) -> int:
        return argmax_random_tie(self.scores(stats), rng)


AUTHORS_UNIFORM_WEIGHT = 0.5
"""The weight of the uniform distribution in :func:`vote_prior` that the authors mix in for
both LLM-MCTS's prior and EP-SayCan's LLM score: a constant of those methods, not a setting."""


def uniform_prior(actions: Sequence[object]) -> np.ndarray:
    """Every action equally likely (the prior when nothing better is known)."""
    if not actions:
        return np.zeros(0)
    return np.full(len(actions), 1.0 / len(actions))


def vote_prior(
    votes: Sequence[Hashable | None],
    actions: Sequence[Hashable],
    samples: int,
    uniform_weight: float,
) -> np.ndarray:
    """(1 - w)·count(a)/samples + w/|actions|, renormalised to sum to 1.

    ``votes`` holds one entry per sample that named an action (None or an action not in
    ``actions`` — unparseable, illegal — counts for nothing); ``samples`` is how many were
    drawn, so the vote term is the empirical frequency over *all* samples (the authors'
    count/5). When some samples named no legal action the mixture sums to less than 1; the
    renormalisation spreads that missing mass in proportion, so the fewer usable votes, the
    closer the prior is to uniform (all unusable: exactly uniform).
    """
    if not 0.0 <= uniform_weight <= 1.0:
        raise ValueError(f"uniform_weight must be in [0, 1], got {uniform_weight}")
    if samples < 1:
        raise ValueError(f"samples must be at least 1, got {samples}")
    if not actions:
        return np.zeros(0)
    index = {action: i for i, action in enumerate(actions)}
    counts = np.zeros(len(actions))
    for vote in votes:
        if vote is not None and vote in index:
            counts[index[vote]] += 1.0
    mixed = (1.0 - uniform_weight) * counts / samples + uniform_weight / len(actions)
    total = float(mixed.sum())
    if total <= 0.0:  # w = 0 and no usable vote
        return uniform_prior(actions)
    return np.asarray(mixed / total)
