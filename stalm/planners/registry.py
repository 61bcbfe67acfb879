"""Every planner by name, built from one plain configuration.

``stalm solve --planner NAME`` and ``stalm experiment`` both go through :func:`build_planner`,
so a planner is configured the same way wherever it runs. A :class:`PlannerConfig` is plain,
picklable data (it crosses process and Ray boundaries); the language-model backend is made
from it inside the process that plans, because a loaded model cannot be shipped.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

from stalm.errors import StalmError
from stalm.llm.backends.base import LLMBackend
from stalm.llm.prompt import PromptOptions
from stalm.planners.base import Planner

Progress = Callable[[str], None]


@dataclass(frozen=True)
class PlannerConfig:
    """What a user can choose about a planner; ``None`` means the planner's paper default."""

    llm: str | None = None
    """Backend spec as ``--llm`` takes it (None: $STALM_LLM or the embedded model)."""
    proposer: str = "llm"
    """Where STaLM's task plans come from: 'llm' or 'symbolic'."""
    sims: int | None = None
    """N_budget; None gives the planner's default (30 for STaLM, 35 for the UCT baselines)."""
    batch: int = 5
    """N_batch: replies per query."""
    constrained: bool | None = None
    """Grammar-constrained replies; None: on for the embedded model only."""
    prompt: PromptOptions = field(default_factory=PromptOptions)
    cache_mode: str = "use"
    """Reply cache: use, refresh, off or replay."""
    cache_file: str | None = None
    """The reply cache's SQLite file (None: the default under $STALM_CACHE_DIR)."""
    feedback: bool | None = None
    """Geometric feedback to the proposer; None: on for the symbolic proposer, off for a
    language model (the paper's method; ``--feedback`` turns it on)."""
    reuse_tree: bool = True
    """Keep the executed child's subtree between real steps (the authors' loop)."""
    execution: str = "progress"
    """What an online tree planner executes without a goal plan: 'progress' (search on
    while nothing promises progress) or 'best_q' (the authors' rule)."""
    kappa_tries: int = 3
    """κ draws per task-plan step in Concretize: the authors' 3 (Algorithm 2 draws 1; with
    one, OPEN's single try fails a third of the task plans at their first step)."""
    backtracks: int | None = None
    """Concretize re-draws a placement whose object blocks a later step at most this many
    times per plan; None: 6 with geometric feedback, 0 without (Algorithm 2)."""
    goal_atom_lost: float = 3.0
    """Reward taken back when an action makes a goal conjunct false (0: the authors')."""
    goal_relations_only: bool = True
    """The symbolic proposer grounds relative placements only for the goal's relations."""

    def __post_init__(self) -> None:
        if self.proposer not in ("llm", "symbolic"):
            raise StalmError(f"unknown proposer '{self.proposer}' (available: llm, symbolic)")
        if self.batch < 1:
            raise StalmError(f"--batch (N_batch) must be at least 1, got {self.batch}")
        if self.sims is not None and self.sims < 1:
            raise StalmError(f"--sims (N_budget) must be at least 1, got {self.sims}")
        if self.execution not in ("progress", "best_q"):
            raise StalmError(
                f"unknown execution rule '{self.execution}' (available: progress, best_q)"
            )
        if self.kappa_tries < 1:
            raise StalmError(f"kappa_tries must be at least 1, got {self.kappa_tries}")


SETTABLE: dict[str, type] = {
    "feedback": bool,
    "reuse_tree": bool,
    "execution": str,
    "kappa_tries": int,
    "backtracks": int,
    "goal_atom_lost": float,
    "goal_relations_only": bool,
    "sims": int,
    "batch": int,
}
"""The :class:`PlannerConfig` fields ``--set KEY=VALUE`` reaches, with their types."""


def with_overrides(config: PlannerConfig, pairs: Sequence[str]) -> PlannerConfig:
    """``config`` with ``KEY=VALUE`` overrides (``--set``), each checked by name and type."""
    changes: dict[str, object] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip().replace("-", "_")
        if not sep or key not in SETTABLE:
            raise StalmError(
                f"--set {pair!r}: expected KEY=VALUE with KEY one of {', '.join(SETTABLE)}"
            )
        kind = SETTABLE[key]
        text = text.strip()
        value: object
        try:
            if kind is bool:
                if text.lower() not in ("true", "false", "1", "0", "on", "off"):
                    raise ValueError(text)
                value = text.lower() in ("true", "1", "on")
            else:
                value = kind(text)
        except ValueError:
            raise StalmError(f"--set {pair!r}: {key} takes a {kind.__name__}") from None
        changes[key] = value
    return replace(config, **changes)  # type: ignore[arg-type]


Builder = Callable[[PlannerConfig, Progress | None], Planner]


@dataclass(frozen=True)
class PlannerEntry:
    """One planner: its name, what it is, whether it needs a language model, how to build it."""

    name: str
    description: str
    uses_llm: bool
    build: Builder


def llm_backend(config: PlannerConfig) -> LLMBackend:
    """The configured backend behind the reply cache."""
    from stalm.llm.backends import make_backend
    from stalm.llm.cache import CachedBackend, ReplyCache

    cache = ReplyCache(config.cache_file) if config.cache_file is not None else None
    return CachedBackend(make_backend(config.llm), cache, mode=config.cache_mode)


def use_constraint(config: PlannerConfig, backend: LLMBackend) -> bool:
    """The embedded model rarely writes a parseable plan unconstrained; servers are free."""
    return backend.name == "embedded" if config.constrained is None else config.constrained


def _stalm_like(name: str) -> Builder:
    def build(config: PlannerConfig, progress: Progress | None) -> Planner:
        from stalm.domain.mdp import RewardSettings
        from stalm.planners.proposers import LLMProposer, TaskPlanProposer
        from stalm.planners.stalm import StalmPlanner, StalmSettings
        from stalm.planners.symbolic import SymbolicProposer
        from stalm.search import SearchSettings

        uct_only = name in ("uct", "uct-hcount")
        proposer: TaskPlanProposer | None = None
        if not uct_only and config.proposer == "symbolic":
            proposer = SymbolicProposer(goal_relations_only=config.goal_relations_only)
        elif not uct_only:
            backend = llm_backend(config)
            proposer = LLMProposer(
                backend, config.prompt, constrained=use_constraint(config, backend)
            )
        budget = config.sims if config.sims is not None else (35 if uct_only else 30)
        feedback = config.feedback
        if feedback is None:
            feedback = config.proposer == "symbolic"
        settings = StalmSettings(
            n_batch=config.batch,
            search=SearchSettings(budget=budget),
            use_tree=name != "stalm-no-uct",
            leaf_value="hcount" if name == "uct-hcount" else "rollout",
            reuse_tree=config.reuse_tree,
            feedback=feedback and not uct_only,
            execution=config.execution,  # type: ignore[arg-type]
            kappa_tries=config.kappa_tries,
            backtracks=config.backtracks
            if config.backtracks is not None
            else (6 if feedback else 0),
            rewards=RewardSettings(goal_atom_lost=config.goal_atom_lost),
            # the symbolic proposer plans with occlusions whatever the prompt options say
            occlusion_predicates=(
                config.proposer == "symbolic" or config.prompt.occlusion_predicates
            ),
        )
        return StalmPlanner(proposer, settings, progress=progress)

    return build


_ENTRIES: list[PlannerEntry] = [
    PlannerEntry(
        "stalm",
        "STaLM: task plans from the proposer, Concretize, warm-started hybrid UCT (N_budget 30)",
        True,
        _stalm_like("stalm"),
    ),
    PlannerEntry(
        "stalm-no-uct",
        "STaLM without UCT (Table 3): Concretize only, then the next action of the best plan",
        True,
        _stalm_like("stalm-no-uct"),
    ),
    PlannerEntry(
        "uct",
        "Hybrid UCT with random rollouts and no guidance (N_budget 35)",
        False,
        _stalm_like("uct"),
    ),
    PlannerEntry(
        "uct-hcount",
        "UCT whose leaf value is Appendix C's Hcount heuristic (N_budget 35)",
        False,
        _stalm_like("uct-hcount"),
    ),
]


def _from_module(module: str, function: str) -> Builder:
    """A builder in its own module, imported only when that planner is built."""

    def build(config: PlannerConfig, progress: Progress | None) -> Planner:
        import importlib

        builder: Builder = getattr(importlib.import_module(module), function)
        return builder(config, progress)

    return build


_ENTRIES += [
    PlannerEntry(
        "ep-saycan",
        "SayCan with an empirical policy: 5 replies to a history-only prompt times precondition "
        "affordance, no search",
        True,
        _from_module("stalm.planners.saycan", "build_ep_saycan"),
    ),
    PlannerEntry(
        "iterative-replanning",
        "One plan per query; on failure re-ask with up to two failed plans and the failure "
        "(5 attempts, then one step)",
        True,
        _from_module("stalm.planners.replanning", "build_iterative_replanning"),
    ),
    PlannerEntry(
        "llm-mcts",
        "MCTS with PUCT whose prior is the first actions of 5 replies at every new node "
        "(N_budget 35)",
        True,
        _from_module("stalm.planners.llm_mcts", "build_llm_mcts"),
    ),
    PlannerEntry(
        "pddlstream-adaptive",
        "PDDLStream's adaptive algorithm: Fast Downward over sampled values as PDDL objects, "
        "failed samples fed back",
        False,
        _from_module("stalm.planners.pddlstream", "build_pddlstream_adaptive"),
    ),
]


def planners() -> dict[str, PlannerEntry]:
    """Every planner by name, in the order the README's table lists them."""
    return {entry.name: entry for entry in _ENTRIES}


def planner_entry(name: str) -> PlannerEntry:
    known = planners()
    if name not in known:
        raise StalmError(f"unknown planner '{name}' (available: {', '.join(known)})")
    return known[name]


def build_planner(
    name: str, config: PlannerConfig | None = None, progress: Progress | None = None
) -> Planner:
    """The planner ``name`` configured by ``config`` (defaults: the paper's settings)."""
    return planner_entry(name).build(config or PlannerConfig(), progress)
