"""What a user can choose about a planner, as plain data, and the backend it names.

A :class:`PlannerConfig` is plain, picklable data (it crosses process and Ray boundaries);
the language-model backend is made from it inside the process that plans
(:func:`llm_backend`), because a loaded model cannot be shipped. These types sit below every
planner module and the registry, so a planner imports them from here and the registry imports
the planners: imports go one way.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

from stalm.errors import StalmError
from stalm.llm.backends.base import LLMBackend
from stalm.llm.prompt import PromptOptions

Progress = Callable[[str], None]
"""Where a planner reports what it is doing (``stalm solve`` prints it)."""


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


def llm_backend(config: PlannerConfig) -> LLMBackend:
    """The configured backend behind the reply cache."""
    from stalm.llm.backends import make_backend
    from stalm.llm.cache import CachedBackend, ReplyCache

    cache = ReplyCache(config.cache_file) if config.cache_file is not None else None
    return CachedBackend(make_backend(config.llm), cache, mode=config.cache_mode)


def use_constraint(config: PlannerConfig, backend: LLMBackend) -> bool:
    """The embedded model rarely writes a parseable plan unconstrained; servers are free."""
    return backend.name == "embedded" if config.constrained is None else config.constrained
