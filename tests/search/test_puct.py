"""PUCT selection and the vote prior on hand-set numbers, and PUCT inside the search."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stalm.domain.actions import DiscreteAction
from stalm.search import SearchPolicies, SearchSettings, SearchTree, warm_started_uct
from stalm.search.puct import PUCTSelection, uniform_prior, vote_prior
from stalm.search.tree import ChildStats
from stalm.world.state import State
from tests.search.synthetic import det, graph, move, state


class TablePriorDouble:
    """A prior source from a table (state name -> probabilities); records every request."""

    def __init__(self, table: dict[str, tuple[float, ...]]) -> None:
        self.table = table
        self.asked: list[str] = []

    def __call__(self, s: State, actions: tuple[DiscreteAction, ...]) -> np.ndarray:
        name = str(s)
        self.asked.append(name)
        return np.asarray(self.table[name])


def stats(q: tuple[float, ...], n: tuple[int, ...], parent: int) -> ChildStats:
    return ChildStats(state("s0"), tuple(move(f"m{i}") for i in range(len(q))), q, n, parent)


def test_puct_scores_by_hand() -> None:
    # parent 3 visits: sqrt(3 + 1) = 2; children (Q, n) = (1, 1), (2, 3), (0, 0)
    hand = stats((1.0, 2.0, 0.0), (1, 3, 0), parent=3)
    prior = TablePriorDouble({"s0": (0.5, 0.25, 0.25)})
    # 1 + 50·0.5·2/2 = 26, 2 + 50·0.25·2/4 = 8.25, 0 + 50·0.25·2/1 = 25
    puct = PUCTSelection(50.0, prior)
    assert puct.scores(hand) == pytest.approx([26.0, 8.25, 25.0])
    assert puct(hand, np.random.default_rng(0)) == 0
    # a prior that favours the unvisited child: 1 + 10 = 11, 2 + 5 = 7, 0 + 60 = 60
    favour = PUCTSelection(50.0, TablePriorDouble({"s0": (0.2, 0.2, 0.6)}))
    assert favour.scores(hand) == pytest.approx([11.0, 7.0, 60.0])
    assert favour(hand, np.random.default_rng(0)) == 2
    # c = 0 is greedy on Q
    assert PUCTSelection(0.0, prior)(hand, np.random.default_rng(0)) == 1
    assert prior.asked == ["s0", "s0", "s0"]


def test_first_selection_at_a_node_follows_the_prior() -> None:
    fresh = stats((0.0, 0.0, 0.0), (0, 0, 0), parent=0)
    prior = TablePriorDouble({"s0": (0.2, 0.7, 0.1)})
    puct = PUCTSelection(50.0, prior)
    # N = 0: sqrt(0 + 1) = 1, so the bonus is c·P: 10, 35, 5
    assert puct.scores(fresh) == pytest.approx([10.0, 35.0, 5.0])
    picks = {puct(fresh, np.random.default_rng(seed)) for seed in range(30)}
    assert picks == {1}, "the prior's favourite, not a uniform draw"
    assert prior.asked == ["s0"] * 31


def test_ties_are_broken_by_the_generator_reproducibly() -> None:
    tied = stats((0.0, 0.0), (1, 1), parent=2)
    puct = PUCTSelection(50.0, TablePriorDouble({"s0": (0.5, 0.5)}))
    first = [puct(tied, np.random.default_rng(seed)) for seed in range(20)]
    again = [puct(tied, np.random.default_rng(seed)) for seed in range(20)]
    assert first == again and set(first) == {0, 1}


def test_a_prior_of_the_wrong_length_is_an_error() -> None:
    puct = PUCTSelection(50.0, TablePriorDouble({"s0": (0.5, 0.5)}))
    with pytest.raises(ValueError, match="2 probabilities for 3 actions"):
        puct.scores(stats((0.0, 0.0, 0.0), (0, 0, 0), parent=1))


def test_vote_prior_counts_over_all_samples_mixes_and_renormalises() -> None:
    actions = ("pick(a)", "pick(b)", "pick(c)", "open(d)")
    # 5 samples: pick(a) twice, pick(b) once, one unparseable (None), one illegal place
    votes = ("pick(a)", "pick(a)", "pick(b)", None, "place(a, on, r)")
    prior = vote_prior(votes, actions, samples=5, uniform_weight=0.5)
    # 0.5·(2/5) + 0.5/4 = 0.325, 0.5·(1/5) + 0.125 = 0.225, 0.125, 0.125; sum 0.8 -> / 0.8
    assert prior == pytest.approx([0.40625, 0.28125, 0.15625, 0.15625])
    assert prior.sum() == pytest.approx(1.0)
    # all five usable: no renormalisation needed
    full = vote_prior(("pick(a)",) * 4 + ("open(d)",), actions, 5, 0.5)
    assert full == pytest.approx([0.525, 0.125, 0.125, 0.225])
    # nothing usable: exactly uniform, also with no uniform mixing at all
    assert vote_prior((None,) * 5, actions, 5, 0.5) == pytest.approx([0.25] * 4)
    assert vote_prior((), actions, 5, 0.0) == pytest.approx([0.25] * 4)
    assert uniform_prior(actions) == pytest.approx([0.25] * 4)
    assert vote_prior(votes, (), 5, 0.5).size == 0
    with pytest.raises(ValueError):
        vote_prior(votes, actions, 5, 1.5)
    with pytest.raises(ValueError):
        vote_prior(votes, actions, 0, 0.5)


def star():
    """s0 with four actions, each to a dead-end leaf, all rewards 0: only the prior differs."""
    return graph([("s0", name, det(f"l{name}")) for name in ("a", "b", "c", "d")])


def test_puct_in_the_search_follows_the_prior_and_asks_only_where_it_selects() -> None:
    mdp = star().as_mdp()
    prior = TablePriorDouble({"s0": (0.7, 0.1, 0.1, 0.1)})
    policies = replace(
        SearchPolicies.from_settings(SearchSettings()),
        select_action=PUCTSelection(50.0, prior),
    )
    tree = SearchTree.for_root(mdp, state("s0"))
    rng = np.random.default_rng(3)
    warm_started_uct(
        mdp, state("s0"), (), rng, settings=SearchSettings(budget=8), policies=policies, tree=tree
    )
    visits = {str(c.action): c.n for c in tree.node(state("s0")).children}
    # from sim 1 on (N = 0 included), 0.7/(1 + n_a) beats 0.1/(1 + n_other) while n_a <= 6:
    # a gets sims 1-7, and only the 8th goes elsewhere
    assert visits["a"] == 7 and sum(visits.values()) == 8
    assert prior.asked == ["s0"] * 8, "asked at every selection at s0; the leaves are ends"
