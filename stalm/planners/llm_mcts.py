"""LLM-MCTS (Zhao et al., 2024), the baseline of §4.2–4.3: MCTS whose prior asks a model.

Every node the search creates gets a prior from the model when it is created (the expansion
step of PUCT-style MCTS, :class:`LLMPrior`): the paper's prompt for the state's predicates is
sent once for N_batch replies, the first action of each parsed plan that is a legal action
counts as a vote, and votes/N_batch is mixed 0.5 with uniform (the authors' construction);
PUCT (:mod:`stalm.search.puct`, c = 50) weighs each legal action by it. So the model is called
once per *new node* -- up to N_budget = 35 calls per real step -- the defining cost of the
method, which the paper blames for its time-outs (§4.3); every call, its tokens and its
seconds go into the result. With ``execution.reuse_tree`` the executed child's subtree is kept
with its nodes' priors, as for every online tree planner. Everything else is STaLM's hybrid
search without warm start: UCT over κ with progressive widening, random rollouts at new
leaves, run online by :class:`~stalm.trial.online.OnlinePlanner`.

Determinism: each state's request is seeded from the trial seed and a stable digest of the state
(never Python's salted ``hash``), so the same seed replays the same cached replies and, with
them, the same search.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from contextlib import nullcontext
from dataclasses import KW_ONLY, dataclass, field, replace

import numpy as np

from stalm.domain.actions import DiscreteAction
from stalm.json_object import JsonObject, record_json
from stalm.planners.registry_rows import planner_rows
from stalm.planners.tree_step import tree_search
from stalm.predicates.literals import GroundLiteral
from stalm.predicates.memo import Timing
from stalm.progress import Progress
from stalm.proposers.protocol import Proposal, ProposalRequest, TaskPlanProposer
from stalm.search import LeafValue, SearchPolicies, SearchSettings
from stalm.search.policies import ValueFunction
from stalm.search.puct import AUTHORS_UNIFORM_WEIGHT, PUCTSelection, uniform_prior, vote_prior
from stalm.search.search_mdp import SearchMDP
from stalm.search.tree import Edge, SearchTree
from stalm.settings.tree import RunSettings
from stalm.trial.online import Decision, OnlinePlanner, Trial
from stalm.trial.query_seeds import state_request_seed
from stalm.world.problem import Problem
from stalm.world.state import State


@dataclass(frozen=True)
class PriorStats:
    """What the LLM prior of one trial cost and how usable its replies were."""

    states: int = 0
    """Nodes given a model prior (one query each; a state is asked again in a later tree)."""
    llm_calls: int = 0
    cached_calls: int = 0
    """Queries answered entirely from the reply cache (no model run)."""
    prompt_tokens: int = 0
    completion_tokens: int = 0
    llm_seconds: float = 0.0
    """Wall seconds the queries took now (a cached reply's original seconds are charged to
    the trial by the episode, not here)."""
    predicate_seconds: float = 0.0
    votes: int = 0
    """Replies whose first action was a legal action at their state."""
    unusable_replies: int = 0
    """Replies without a plan or whose first action was not legal there."""
    deadline_fallbacks: int = 0
    """Priors answered uniform because the trial's deadline had passed."""


@dataclass(frozen=True)
class LlmMctsDetails:
    """LLM-MCTS's record of a trial: its proposer, what its prior cost, the model calls of
    each real step and, with tree reuse only (else None), the visits each kept root had."""

    proposer: str
    prior: PriorStats
    llm_calls_per_step: tuple[int, ...]
    reused_root_visits: tuple[int, ...] | None

    def to_json(self) -> JsonObject:
        return record_json(self, omitted_when_none={"reused_root_visits"})


@dataclass(eq=False)
class LLMPrior:
    """A :class:`~stalm.search.puct.PriorSource` that asks a task-plan proposer once per node.

    The first time a state needs a prior in the current tree (its node is created,
    :class:`AskAtNewNodes`, or it is the root), the proposer is asked for ``samples`` task
    plans for its literals (``literals_of``) with a seed from :func:`state_request_seed`; the
    plans' first actions are :func:`~stalm.search.puct.vote_prior`'s votes, kept until
    :meth:`new_tree` or :meth:`keep_only` forgets them.

    ``on_query`` gets every query's :class:`Proposal` (the trial records it and charges its
    seconds); ``timing`` keeps the query's wall time out of the tree search's phase. Once
    ``deadline()`` has passed (read at each check, so what the trial charges for cached
    replies holds here too), the prior is uniform and not kept, so the search returns
    quickly; a query under way is never cut off: a trial overruns by at most one query.
    """

    problem: Problem
    proposer: TaskPlanProposer
    literals_of: Callable[[State], Iterable[GroundLiteral]]
    _: KW_ONLY
    trial_seed: int
    samples: int
    deadline: Callable[[], float] | None = None
    progress: Progress | None = None
    on_query: Callable[[Proposal], None] | None = None
    timing: Timing | None = None
    stats: PriorStats = field(default_factory=PriorStats, init=False)
    _votes: dict[State, tuple[DiscreteAction, ...]] = field(default_factory=dict, init=False)

    def new_tree(self) -> None:
        """Forget every prior: the next search builds a new tree, whose nodes ask anew."""
        self._votes = {}

    def keep_only(self, tree: SearchTree) -> None:
        """Forget the priors of states that are not nodes of ``tree`` (the subtree kept after
        a real step): a state the new search reaches outside it is a new node, which asks."""
        self._votes = {state: votes for state, votes in self._votes.items() if state in tree}

    def prepare(self, state: State, actions: tuple[DiscreteAction, ...]) -> None:
        """Make sure ``state`` has its prior in this tree (asking the model if it has not)."""
        self._votes_for(state, actions)

    def __call__(self, state: State, actions: tuple[DiscreteAction, ...]) -> np.ndarray:
        votes = self._votes_for(state, actions)
        if votes is None:
            return uniform_prior(actions)
        return vote_prior(votes, actions, self.samples, AUTHORS_UNIFORM_WEIGHT)

    def _votes_for(
        self, state: State, actions: tuple[DiscreteAction, ...]
    ) -> tuple[DiscreteAction, ...] | None:
        """The state's votes, asked for now if needed; None once the deadline has passed."""
        votes = self._votes.get(state)
        if votes is None:
            deadline = self._deadline_now()
            if deadline is not None and time.monotonic() >= deadline:
                self.stats = replace(
                    self.stats, deadline_fallbacks=self.stats.deadline_fallbacks + 1
                )
                return None
            votes = self._ask(state, actions)
            self._votes[state] = votes
        return votes

    def _deadline_now(self) -> float | None:
        return None if self.deadline is None else self.deadline()

    def _ask(self, state: State, actions: tuple[DiscreteAction, ...]) -> tuple[DiscreteAction, ...]:
        """Query the proposer for ``state``; the legal first actions of its plans."""
        if self.progress is not None:
            self.progress(f"llm-mcts: prior for new node #{self.stats.states + 1}")
        tick = time.monotonic()
        literals = frozenset(self.literals_of(state))
        predicate_seconds = time.monotonic() - tick
        tick = time.monotonic()
        seed = state_request_seed(self.trial_seed, state)
        # the episode charges the query's seconds (on_query): none go to the enclosing phase
        with self.timing.timed(None) if self.timing is not None else nullcontext():
            proposal = self.proposer.propose(
                ProposalRequest(
                    self.problem, state, literals, self.samples, seed, self._deadline_now()
                )
            )
        llm_seconds = time.monotonic() - tick
        if self.on_query is not None:
            self.on_query(proposal)
        legal = set(actions)
        votes = tuple(plan[0] for plan in proposal.plans if plan and plan[0] in legal)
        replies = len(proposal.plans) + len(proposal.unparseable) + len(proposal.no_plan)
        stats = self.stats
        self.stats = replace(
            stats,
            states=stats.states + 1,
            llm_calls=stats.llm_calls + proposal.calls,
            cached_calls=stats.cached_calls + int(proposal.from_cache),
            prompt_tokens=stats.prompt_tokens + proposal.prompt_tokens,
            completion_tokens=stats.completion_tokens + proposal.completion_tokens,
            llm_seconds=stats.llm_seconds + llm_seconds,
            predicate_seconds=stats.predicate_seconds + predicate_seconds,
            votes=stats.votes + len(votes),
            unusable_replies=stats.unusable_replies + replies - len(votes),
        )
        return votes


@dataclass(frozen=True)
class AskAtNewNodes:
    """LLM-MCTS's expansion: every node the search creates gets its prior right away.

    Wraps the leaf value (a random rollout): the search calls it exactly once per new node,
    with the node's state, so asking the prior there is one model call per new node, whether
    or not the search later selects from that node.
    """

    prior: LLMPrior
    value: ValueFunction

    def __call__(
        self,
        mdp: SearchMDP,
        state: State,
        depth: int,
        rng: np.random.Generator,
        arrival: Edge | None = None,
    ) -> LeafValue:
        self.prior.prepare(state, mdp.legal_actions(state))
        return self.value(mdp, state, depth, rng, arrival=arrival)


def llm_mcts_policies(settings: SearchSettings, prior: LLMPrior) -> SearchPolicies:
    """STaLM's search policies with PUCT over ``prior`` at discrete nodes and the prior asked
    for at every node the search creates (:class:`AskAtNewNodes`)."""
    plain = SearchPolicies.from_settings(settings)
    puct = PUCTSelection(settings.c, prior)
    return replace(plain, select_action=puct, value=AskAtNewNodes(prior, plain.value))


@dataclass(frozen=True)
class LlmMcts:
    """LLM-MCTS's part of a planner: the proposer its prior asks, what it reads of the
    settings tree, where its prior reports progress; called at a trial's start, its steps."""

    proposer: TaskPlanProposer
    settings: RunSettings
    progress: Progress | None = None

    def __call__(self, trial: Trial) -> LlmMctsSteps:
        return LlmMctsSteps(self, trial)


def LlmMctsPlanner(
    proposer: TaskPlanProposer,
    settings: RunSettings | None = None,
    progress: Progress | None = None,
) -> OnlinePlanner:
    """LLM-MCTS run online: search from the current state, execute, repeat. ``settings`` is
    the run's settings tree (None: :class:`RunSettings`' defaults, which ``stalm solve
    --planner llm-mcts`` runs; N_budget: its registry row's), N_batch replies per prior
    (``search.batch``). The trial computes the occlusion literals only for a prompt that
    shows them."""
    run_settings = planner_rows()["llm-mcts"].settings_for(settings or RunSettings())
    method = LlmMcts(proposer, run_settings, progress)
    occlusion = run_settings.prompt.occlusion_predicates
    return OnlinePlanner("llm-mcts", run_settings, method, progress, occlusion=occlusion)


class LlmMctsSteps:
    """One trial's real steps: MCTS with the LLM prior from the current state, then execute
    its goal plan or its best root action."""

    def __init__(self, planner: LlmMcts, trial: Trial) -> None:
        self.planner = planner
        self.trial = trial
        settings = planner.settings
        self.prior = LLMPrior(
            trial.episode.problem,
            planner.proposer,
            lambda state: trial.memo.of(state).literals,
            trial_seed=trial.seed,
            samples=settings.search.batch,
            deadline=lambda: trial.episode.deadline,
            progress=planner.progress,
            on_query=trial.episode.record_query,
            timing=trial.episode.clock,
        )
        self.policies = llm_mcts_policies(settings.search.search_settings(), self.prior)
        self.calls_per_step: list[int] = []

    def decide(self) -> Decision:
        trial, prior = self.trial, self.prior
        search = trial.within_horizon(self.planner.settings.search.search_settings())
        trial.replans += 1
        trial.say(f"step {trial.done}: MCTS with an LLM prior, {search.budget} sims")
        tree = trial.tree_at(trial.episode.state) if trial.reuse_tree else None
        if tree is None:
            prior.new_tree()
        else:
            prior.keep_only(tree)
        calls_before = prior.stats.llm_calls
        result = tree_search(trial, (), search, self.policies, tree)
        self.calls_per_step.append(prior.stats.llm_calls - calls_before)
        if result.goal_plan:
            return result.goal_plan
        if result.best_action is not None:
            return (result.best_action,)
        return ()  # no feasible root action found: search again from the same state

    def details(self) -> LlmMctsDetails:
        trial, name = self.trial, self.planner.proposer.name
        reused = tuple(trial.reused_root_visits) if trial.reuse_tree else None
        return LlmMctsDetails(name, self.prior.stats, tuple(self.calls_per_step), reused)
