"""Every setting of a run as one frozen tree: what ``--show-settings`` prints and records keep.

:class:`RunSettings` composes the layers' settings -- their own dataclasses where they exist
(:class:`~stalm.domain.mdp.RewardSettings`, :class:`~stalm.domain.samplers.SamplerSettings`,
:class:`~stalm.predicates.samples.PredicateSettings`, :class:`~stalm.llm.prompt.PromptOptions`),
and a small section here where a planner-level choice has no dataclass of its own -- so that a
run is one value: built from the defaults, a file and ``--set`` overrides
(:mod:`stalm.settings.io`), passed explicitly to the planner builders of
:mod:`stalm.planners.registry`, and written whole into every result record, from which
``stalm rerun`` runs the trial again.

Every default of a run is written here or in a layer dataclass the tree composes, and nowhere
else: the planners read this tree and its sections themselves, and a planner built without
one reads ``RunSettings()``, so the Python API runs what ``stalm solve`` runs. The values are
checked here too, once, by the sections. A ``None`` means "decided per planner or per
problem"; :meth:`RunSettings.resolved` replaces every such ``None`` by the value the run uses,
and that resolved tree is what a record keeps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

from stalm.domain.mdp import RewardSettings
from stalm.domain.samplers import SamplerSettings
from stalm.errors import StalmError
from stalm.llm.cache import CacheMode
from stalm.llm.prompt import PromptOptions
from stalm.predicates.samples import PredicateSettings
from stalm.search import SearchSettings
from stalm.search.concretize import FIGURE5_KINDS, Figure5Kind
from stalm.world.problem import Problem

ExecutionRule = Literal["progress", "best_q"]
ProposerKind = Literal["llm", "symbolic", "noisy"]
PROPOSER_KINDS: tuple[str, ...] = ("llm", "symbolic", "noisy")
InnerProposer = Literal["symbolic", "llm"]
NoiseKind = Figure5Kind
NOISE_KINDS: tuple[NoiseKind, ...] = FIGURE5_KINDS
"""Figure 5's three kinds of task-plan error, in the order of ``proposer.noise.weights``."""

FEEDBACK_BACKTRACKS = 6
"""``execution.backtracks`` when it is None and geometric feedback is on (0 without)."""

FLAT_NAMES: dict[str, str] = {
    "llm": "llm.backend",
    "proposer": "proposer.kind",
    "sims": "search.sims",
    "batch": "search.batch",
    "constrained": "llm.constrained",
    "cache_mode": "llm.cache",
    "cache_file": "llm.cache_file",
    "feedback": "execution.feedback",
    "reuse_tree": "execution.reuse_tree",
    "execution": "execution.rule",
    "kappa_tries": "execution.kappa_tries",
    "backtracks": "execution.backtracks",
    "goal_atom_lost": "rewards.goal_atom_lost",
    "goal_relations_only": "proposer.goal_relations_only",
}
"""The flat names of the settings before the tree (still taken by ``--set``, settings files
and records, and what a trial's key is computed from) and the tree path each one is."""


def _check(section: str, owner: object, *checks: tuple[str, bool, str]) -> None:
    """One StalmError naming the first setting that fails its check (name, ok, expected)."""
    for name, ok, expected in checks:
        if not ok:
            raise StalmError(
                f"setting {section}.{name} must be {expected}, got {getattr(owner, name)!r}"
            )


@dataclass(frozen=True)
class BudgetSection:
    """What one trial may spend; None: the problem file's (the paper's 300/600 s, H = 20)."""

    time_budget_s: float | None = None
    """Wall-clock seconds of the trial (``--time-budget``)."""
    horizon: int | None = None
    """Real actions the trial may execute (the problem's horizon H)."""

    def __post_init__(self) -> None:
        budget, horizon = self.time_budget_s, self.horizon
        positive = budget is None or (math.isfinite(budget) and budget > 0)
        _check(
            "budget",
            self,
            ("time_budget_s", positive, "a positive number of seconds"),
            ("horizon", horizon is None or horizon >= 1, "an integer >= 1"),
        )


_PAPER_SEARCH = SearchSettings()
"""The search layer's defaults (the paper's constants), which :class:`SearchSection` takes as
its own so that they are written in one place."""


@dataclass(frozen=True)
class SearchSection:
    """The tree search and the proposer's batch (Appendix B; §4.2 for the baselines).

    ``c``, ``k``, ``alpha``, ``gamma`` and ``horizon`` are :class:`~stalm.search.SearchSettings`'s
    (checked by it); ``horizon`` is the H of the search's simulations and rollouts, which
    ``budget.horizon`` (the real steps of a trial) does not change.
    """

    sims: int | None = None
    """N_budget, simulations per real step; None: the planner's (its row of the registry)."""
    batch: int = 5
    """N_batch: task plans (replies) per query."""
    c: float = _PAPER_SEARCH.c
    k: float = _PAPER_SEARCH.k
    alpha: float = _PAPER_SEARCH.alpha
    gamma: float = _PAPER_SEARCH.gamma
    horizon: int = _PAPER_SEARCH.horizon

    def __post_init__(self) -> None:
        _check(
            "search",
            self,
            ("sims", self.sims is None or self.sims >= 1, "an integer >= 1"),
            ("batch", self.batch >= 1, "an integer >= 1"),
        )
        self.search_settings(1)  # c, k, alpha, gamma and horizon: checked by the search layer

    def search_settings(self, budget: int | None = None) -> SearchSettings:
        """The search layer's settings with N_budget ``budget`` (None: ``sims``, which the
        planner's row of the registry fills when it is None)."""
        budget = self.sims if budget is None else budget
        if budget is None:
            raise ValueError("search.sims is None: this planner runs no tree search")
        return SearchSettings(
            c=self.c,
            k=self.k,
            alpha=self.alpha,
            gamma=self.gamma,
            horizon=self.horizon,
            budget=budget,
        )


@dataclass(frozen=True)
class NoiseSection:
    """The noisy proposer (``proposer.kind: noisy``): a degraded proposer, never a language
    model, that corrupts the plans of another on purpose with Figure 5's kinds of error, so
    that what the warm-started tree repairs can be measured offline
    (:mod:`stalm.proposers.noisy`)."""

    rate: float = 0.5
    """p: each task plan of a batch is corrupted with this probability."""
    weights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    """Relative weights of the kind a corrupted plan gets, in the order of
    :data:`NOISE_KINDS` (precondition violation, lack of 3D understanding, partially
    achieved goal); uniform by default. Only kinds that apply to the plan are drawn."""
    inner: InnerProposer = "symbolic"
    """The proposer whose plans are corrupted: 'symbolic' (Fast Downward) or 'llm'."""

    def __post_init__(self) -> None:
        weights = self.weights
        _check(
            "proposer.noise",
            self,
            ("rate", math.isfinite(self.rate) and 0.0 <= self.rate <= 1.0, "in [0, 1]"),
            (
                "weights",
                len(weights) == len(NOISE_KINDS)
                and all(math.isfinite(w) and w >= 0 for w in weights)
                and sum(weights) > 0,
                f"{len(NOISE_KINDS)} numbers >= 0, not all 0 ({', '.join(NOISE_KINDS)})",
            ),
            ("inner", self.inner in ("symbolic", "llm"), "symbolic or llm"),
        )


@dataclass(frozen=True)
class ProposerSection:
    """Where STaLM's task plans come from."""

    kind: ProposerKind = "llm"
    """'llm' (a language model, ``llm``), 'symbolic' (Fast Downward, no model) or 'noisy'
    (another proposer's plans corrupted on purpose, ``noise``: never a language model)."""
    goal_relations_only: bool = True
    """The symbolic proposer grounds relative placements only for the goal's relations."""
    break_occlusion_cycles: bool = True
    """When the predicate abstraction has no plan, the symbolic proposer plans once more
    without the pick occlusions that lie on a cycle (beyond the paper:
    :mod:`stalm.proposers.occlusion_cycles`)."""
    needed_objects_only: bool = True
    """The symbolic proposer gives Fast Downward only the movable objects an action on which
    can matter (beyond the paper: :mod:`stalm.proposers.task_objects`)."""
    noise: NoiseSection = field(default_factory=NoiseSection)

    def __post_init__(self) -> None:
        if self.kind not in PROPOSER_KINDS:
            raise StalmError(
                f"unknown proposer '{self.kind}' (available: {', '.join(PROPOSER_KINDS)})"
            )

    def asks_model(self) -> bool:
        """Whether the task plans come from a language model (the noisy proposer's only when
        it wraps one)."""
        return self.kind == "llm" or (self.kind == "noisy" and self.noise.inner == "llm")


@dataclass(frozen=True)
class LlmSection:
    """The language model and its reply cache (``--llm``, ``--cache``)."""

    backend: str | None = None
    """Backend spec as ``--llm`` takes it; None: $STALM_LLM, a server in
    $STALM_LLM_BASE_URL, or the embedded model."""
    constrained: bool | None = None
    """Grammar-constrained replies; None: on for the embedded model only."""
    cache: CacheMode = "use"
    """Reply cache: use, refresh, off or replay (a miss is an error)."""
    cache_file: str | None = None
    """The reply cache's SQLite file; None: the default under $STALM_CACHE_DIR."""
    from_record: bool = False
    """The backend is the one a re-run record names, not one the user named: it is never
    built nor contacted, and its replies come from the reply cache alone (``stalm rerun``
    sets this; a record's own value is never taken)."""

    def __post_init__(self) -> None:
        if self.cache not in ("use", "refresh", "off", "replay"):
            raise StalmError(
                f"unknown reply cache mode '{self.cache}' (available: use, refresh, off, replay)"
            )


@dataclass(frozen=True)
class ExecutionSection:
    """What a real step does beyond the search: this implementation's additions to the paper,
    each one setting away from the paper's (or the authors') way."""

    rule: ExecutionRule = "progress"
    """Without a goal plan: 'progress' (execute a root action the tree knows leads to goal
    progress, else search on) or 'best_q' (the authors' highest-Q root action)."""
    reuse_tree: bool = True
    """Keep the executed child's subtree as the next step's tree (every online tree
    planner: STaLM, UCT, UCT-Hcount, LLM-MCTS)."""
    feedback: bool | None = None
    """Geometric feedback to the proposer; None: on for the symbolic proposer, off for a
    language model (the paper's method) and for the noisy proposer (whose point is to see the
    tree repair its plans; on, the noisy proposer passes it to the proposer it wraps)."""
    feedback_rounds: int = 8
    """At most this many proposals per real step with feedback."""
    search_rounds: int = 10
    """'progress' rule: at most this many searches of N_budget simulations from one root
    before falling back to the best-Q root action. A count, not a time, so that the same
    seed makes the same decisions on a fast machine and on a slow one."""
    step_share: float = 1.0
    """Share of the remaining time one real step may spend asking again or searching on, a
    guard beside the two counts above; 1.0: none but the trial's deadline (decisions then do
    not depend on the machine's speed)."""
    kappa_tries: int = 3
    """κ draws per task-plan step in Concretize (and per chosen action in EP-SayCan): the
    authors' 3 (Algorithm 2 draws 1)."""
    backtracks: int | None = None
    """Placement re-draws per plan in Concretize; None: 6 with feedback, 0 without."""

    def __post_init__(self) -> None:
        if self.rule not in ("progress", "best_q"):
            raise StalmError(f"unknown execution rule '{self.rule}' (available: progress, best_q)")
        backtracks = self.backtracks
        _check(
            "execution",
            self,
            ("feedback_rounds", self.feedback_rounds >= 1, "an integer >= 1"),
            ("search_rounds", self.search_rounds >= 1, "an integer >= 1"),
            ("step_share", 0.0 < self.step_share <= 1.0, "in (0, 1]"),
            ("kappa_tries", self.kappa_tries >= 1, "an integer >= 1"),
            ("backtracks", backtracks is None or backtracks >= 0, "an integer >= 0"),
        )


@dataclass(frozen=True)
class RunSettings:
    """The whole settings tree of one run (see the module docstring)."""

    budget: BudgetSection = field(default_factory=BudgetSection)
    search: SearchSection = field(default_factory=SearchSection)
    rewards: RewardSettings = field(default_factory=RewardSettings)
    samplers: SamplerSettings = field(default_factory=SamplerSettings)
    predicates: PredicateSettings = field(default_factory=PredicateSettings)
    proposer: ProposerSection = field(default_factory=ProposerSection)
    llm: LlmSection = field(default_factory=LlmSection)
    prompt: PromptOptions = field(default_factory=PromptOptions)
    execution: ExecutionSection = field(default_factory=ExecutionSection)

    def feedback(self) -> bool:
        """Whether geometric feedback is on in this run (``execution.feedback`` resolved)."""
        feedback = self.execution.feedback
        return feedback if feedback is not None else self.proposer.kind == "symbolic"

    def backtracks(self) -> int:
        """Concretize's backtracks in this run (``execution.backtracks`` resolved)."""
        backtracks = self.execution.backtracks
        if backtracks is not None:
            return backtracks
        return FEEDBACK_BACKTRACKS if self.feedback() else 0

    def resolved(self, problem: Problem | None = None) -> RunSettings:
        """This tree with every None that :class:`RunSettings` decides replaced by the value
        the run (on ``problem``, for the budget and the predicates' scope) uses. Resolving
        twice changes nothing; N_budget's and the language model's Nones are the registry's
        (it knows each planner's budget and which planners ask a model)."""
        execution = replace(self.execution, feedback=self.feedback(), backtracks=self.backtracks())
        budget, predicates = self.budget, self.predicates
        if problem is not None:
            predicates = predicates.for_objects(len(problem.spec.objects))
            seconds, horizon = budget.time_budget_s, budget.horizon
            budget = BudgetSection(
                time_budget_s=problem.spec.time_budget_s if seconds is None else seconds,
                horizon=problem.horizon if horizon is None else horizon,
            )
        return replace(self, budget=budget, execution=execution, predicates=predicates)


def with_budget(problem: Problem, budget: BudgetSection) -> Problem:
    """``problem`` with ``budget.horizon`` as its horizon (itself if that changes nothing)."""
    if budget.horizon is None or budget.horizon == problem.horizon:
        return problem
    return Problem(problem.spec.model_copy(update={"horizon": budget.horizon}), problem.source)
