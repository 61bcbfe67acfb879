"""EP-SayCan (§4.2): a fresh decision at every real step, LLM score times affordance, no search.

SayCan multiplies a language model's likelihood of each skill by the skill's affordance and
executes the argmax. GPT-4 gives no log-probabilities of prompt tokens, so the paper (after Zhao
et al., 2024) uses the *empirical* policy: ask N_batch = 5 replies at temperature 1 and count
the replies whose plan starts with each action. As in the authors' code, the LLM score is the
same prior LLM-MCTS uses (:func:`stalm.search.puct.vote_prior`): votes/5 mixed 0.5 with uniform
over the legal actions, so an affordable action the replies never named still scores above 0.
The prompt is SayCan's own (task, action vocabulary, history; :mod:`stalm.llm.saycan_prompt`),
without STaLM's predicates; that is the point of the baseline. Affordance is 1 when the action's
symbolic precondition holds and the state's geometric predicates do not mark it occluded
(PickOccludedBy for PICK, PlaceOccludedBy for PLACE), else 0 -- the authors removed occluded
actions before the argmax.

One step: compute the predicates, query, score, take the argmax (ties broken by the trial's
generator), draw κ with ψ up to 3 times and execute the first feasible draw. An action without a
feasible κ is excluded at this state and the next best is taken. When every product is 0 the
step cannot go on: if no affordable action is left, asking again cannot help and the trial ends
as 'no_progress' at once; if the replies alone gave the affordable actions no mass (possible only
with ``uniform_weight = 0``), the planner asks again with the next derived seed, up to
``max_queries_per_step`` queries at one state.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Collection, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from stalm.domain.actions import DiscreteAction, Pick, Place
from stalm.domain.mdp import Domain
from stalm.domain.outcome import Infeasibility
from stalm.domain.params import Action
from stalm.domain.vocabulary import Vocabulary
from stalm.json_object import JsonObject
from stalm.llm.backends.base import LLMBackend
from stalm.llm.saycan_prompt import saycan_prompt
from stalm.predicates.literals import GroundLiteral
from stalm.progress import Progress
from stalm.proposers.language_model import ask_for_task_plans
from stalm.proposers.model_backend import use_constraint
from stalm.search.puct import AUTHORS_UNIFORM_WEIGHT, vote_prior
from stalm.settings.tree import RunSettings
from stalm.trial.details import DirectRecord
from stalm.trial.episode import Episode
from stalm.trial.online import Decision, OnlinePlanner, Trial
from stalm.trial.query_seeds import query_seed
from stalm.world.state import State

Affordance = Callable[[DiscreteAction], bool]


@dataclass(frozen=True)
class SayCanScore:
    """One candidate action's votes (replies whose plan starts with it), its LLM score (the
    votes mixed with uniform), its 0/1 affordance and their product, which SayCan maximises."""

    action: DiscreteAction
    votes: int
    llm: float
    affordance: float

    @property
    def score(self) -> float:
        return self.llm * self.affordance


def saycan_scores(
    first_actions: Iterable[DiscreteAction],
    n_replies: int,
    candidates: Sequence[DiscreteAction],
    affordable: Affordance,
    uniform_weight: float = AUTHORS_UNIFORM_WEIGHT,
) -> tuple[SayCanScore, ...]:
    """SayCan's scores of ``candidates`` from the first actions of ``n_replies`` replies.

    The LLM score is :func:`vote_prior` over the candidates: (1 - w)·votes/``n_replies`` +
    w/|candidates|, renormalised (replies without a readable first action and first actions
    outside ``candidates`` count in the denominator but vote for nothing).
    """
    firsts = list(first_actions)
    counts = Counter(firsts)
    prior = vote_prior(firsts, candidates, n_replies, uniform_weight)
    return tuple(
        SayCanScore(action, counts[action], float(p), 1.0 if affordable(action) else 0.0)
        for action, p in zip(candidates, prior, strict=True)
    )


def saycan_choice(
    scores: Sequence[SayCanScore],
    rng: np.random.Generator,
    excluded: Collection[DiscreteAction] = (),
) -> DiscreteAction | None:
    """The argmax of LLM score × affordance over actions not ``excluded`` (None if all are 0).

    Ties are broken uniformly with ``rng`` among the tied actions in ``scores`` order, so the
    choice is a function of the seed.
    """
    live = [s for s in scores if s.score > 0.0 and s.action not in excluded]
    if not live:
        return None
    best = max(s.score for s in live)
    tied = [s.action for s in live if s.score == best]
    return tied[int(rng.integers(len(tied)))] if len(tied) > 1 else tied[0]


def occlusion_free(literals: Iterable[GroundLiteral]) -> Affordance:
    """Whether an action is not occluded per the state's PickOccludedBy/PlaceOccludedBy."""
    picks: set[str] = set()
    places: set[tuple[str, ...]] = set()
    for literal in literals:
        if literal.name == "PickOccludedBy":
            picks.add(literal.args[0])
        elif literal.name == "PlaceOccludedBy":
            places.add(literal.args[:3])

    def free(action: DiscreteAction) -> bool:
        if isinstance(action, Pick):
            return action.obj not in picks
        if isinstance(action, Place):
            return (action.obj, action.direction, action.ref) not in places
        return True

    return free


def affordance(domain: Domain, state: State, literals: Iterable[GroundLiteral]) -> Affordance:
    """SayCan's 0/1 affordance in ``state``: the symbolic precondition holds and the action is
    not occluded according to the state's geometric predicates ``literals``."""
    unoccluded = occlusion_free(literals)

    def affordable(action: DiscreteAction) -> bool:
        return domain.precondition_failure(state, action) is None and unoccluded(action)

    return affordable


@dataclass(frozen=True)
class SayCanDecision:
    """What one query saw and what it chose (None: every score was 0): the replies' first
    actions, and each candidate's votes, LLM score and affordance."""

    step: int
    query: int
    first_actions: tuple[DiscreteAction, ...]
    scores: tuple[SayCanScore, ...]
    chosen: DiscreteAction | None

    def to_json(self) -> JsonObject:
        """As the result file keeps it: only the candidates some reply voted for
        (``voted``: action, votes, LLM score to 6 places, affordance)."""
        return {
            "step": self.step,
            "query": self.query,
            "first_actions": [list(action.as_tuple()) for action in self.first_actions],
            "voted": [
                [list(s.action.as_tuple()), s.votes, round(s.llm, 6), s.affordance]
                for s in self.scores
                if s.votes > 0
            ],
            "chosen": None if self.chosen is None else list(self.chosen.as_tuple()),
        }


@dataclass
class DecisionTally:
    """What the decisions of one trial did, for the result's details."""

    queries: int = 0
    zero_score_queries: int = 0
    kappa_failures: int = 0
    decisions: list[SayCanDecision] = field(default_factory=list)


@dataclass(frozen=True)
class SayCanDetails(DirectRecord):
    """EP-SayCan's record of a trial: the model asked and what its decisions did."""

    backend: str
    queries: int
    zero_score_queries: int
    kappa_failures: int
    decisions: tuple[SayCanDecision, ...]


@dataclass(frozen=True)
class SayCanConstants:
    """EP-SayCan's own constants, which the settings tree does not hold: the replies' votes
    mixed 0.5 with uniform (the authors' prior), the queries per state, the temperature."""

    uniform_weight: float = AUTHORS_UNIFORM_WEIGHT
    """Weight of the uniform distribution in the LLM score; 0 scores by the votes alone."""
    max_queries_per_step: int = 3
    """Queries at one state whose replies gave every affordable action a score of 0 before the
    trial ends as 'no_progress' (only reachable with ``uniform_weight = 0``)."""
    temperature: float = 1.0


@dataclass(frozen=True)
class SayCan:
    """EP-SayCan's part of a planner: the model, whether its replies are constrained, the run's
    settings tree (N_batch replies per decision, ``search.batch``; κ draws per chosen action,
    ``execution.kappa_tries``) and the method's own constants; called at a trial's start, its
    steps (:class:`SayCanSteps`)."""

    backend: LLMBackend
    constrained: bool
    settings: RunSettings
    constants: SayCanConstants = SayCanConstants()

    def __call__(self, trial: Trial) -> SayCanSteps:
        return SayCanSteps(self, trial)

    def decide(
        self,
        domain: Domain,
        episode: Episode,
        literals: Iterable[GroundLiteral],
        seed: int,
        step: int,
        rng: np.random.Generator,
        tally: DecisionTally,
    ) -> Action | None:
        """One SayCan decision in the current state: a feasible sampled action, or None."""
        problem, state, say = episode.problem, episode.state, episode.observer.message
        batch, weight = self.settings.search.batch, self.constants.uniform_weight
        affordable = affordance(domain, state, literals)
        candidates = domain.legal_actions(state)
        history = [action.discrete for action in episode.executed]
        excluded: set[DiscreteAction] = set()
        for attempt in range(self.constants.max_queries_per_step):
            if episode.out_of_time():
                return None
            say(f"step {step}: asking for {batch} replies")
            proposal = ask_for_task_plans(
                self.backend,
                Vocabulary.from_problem(problem),
                saycan_prompt(problem, history),
                batch,
                query_seed(seed, step, attempt),
                constrained=self.constrained,
                temperature=self.constants.temperature,
                deadline=episode.deadline,
            )
            episode.record_query(proposal)
            episode.failures.update("unparseable" for _ in proposal.unparseable)
            tally.queries += 1
            firsts = tuple(plan[0] for plan in proposal.plans)
            n_replies = len(proposal.replies) or batch
            scores = saycan_scores(firsts, n_replies, candidates, affordable, weight)
            while not episode.out_of_time():
                best = saycan_choice(scores, rng, excluded)
                if best is None:
                    break
                chosen = self._draw_kappa(domain, state, best, rng)
                if chosen is not None:
                    tally.decisions.append(
                        SayCanDecision(step, attempt, firsts, scores, chosen.discrete)
                    )
                    return chosen
                tally.kappa_failures += 1
                excluded.add(best)
                say(f"step {step}: no feasible κ for {best}; excluded at this state")
            tally.zero_score_queries += 1
            tally.decisions.append(SayCanDecision(step, attempt, firsts, scores, None))
            if not any(affordable(a) and a not in excluded for a in candidates):
                say(f"step {step}: no affordable action left in this state")
                return None
        return None

    def _draw_kappa(
        self, domain: Domain, state: State, action: DiscreteAction, rng: np.random.Generator
    ) -> Action | None:
        """The first of up to ``kappa_tries`` draws of ψ that is feasible, or None."""
        for _ in range(self.settings.execution.kappa_tries):
            drawn = domain.sample(state, action, rng)
            if not isinstance(drawn, Infeasibility):
                return drawn
        return None


@dataclass
class SayCanSteps:
    """One trial's decisions: the current state's predicates, then :meth:`SayCan.decide`;
    no affordable action with a feasible κ ends the trial."""

    planner: SayCan
    trial: Trial
    tally: DecisionTally = field(default_factory=DecisionTally)
    step: int = 0

    def decide(self) -> Decision:
        trial = self.trial
        trial.say(f"step {self.step}: predicates")
        literals = trial.episode.predicates().literals
        chosen = self.planner.decide(
            trial.domain, trial.episode, literals, trial.seed, self.step, trial.rng, self.tally
        )
        trial.replans = self.tally.queries
        if chosen is None:
            return "timeout" if trial.episode.out_of_time() else "no_progress"
        self.step += 1
        return (chosen,)

    def details(self) -> SayCanDetails:
        backend, tally = self.planner.backend, self.tally
        return SayCanDetails(
            f"{backend.name}:{backend.model}",
            tally.queries,
            tally.zero_score_queries,
            tally.kappa_failures,
            tuple(tally.decisions),
        )


def EpSayCanPlanner(
    backend: LLMBackend, settings: RunSettings | None = None, progress: Progress | None = None
) -> OnlinePlanner:
    """SayCan with the empirical LLM policy and precondition-and-occlusion affordance.

    ``settings`` is the run's settings tree (None: :class:`RunSettings`' defaults, which
    ``stalm solve --planner ep-saycan`` runs): N_batch and κ tries come from it, and whether
    replies are constrained is its ``llm.constrained`` (None: for the embedded model only).
    R's constants are the domain's own and predicates include the occlusion literals (the
    affordance reads them)."""
    run_settings = settings or RunSettings()
    method = SayCan(backend, use_constraint(run_settings, backend), run_settings)
    return OnlinePlanner("ep-saycan", run_settings, method, progress)
