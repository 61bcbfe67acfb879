"""The common choices about a planner as flat data, and the backend the settings name.

:class:`PlannerConfig` is the short way to say the usual choices (``PlannerConfig(proposer=
"symbolic", sims=30)``); it stands for the settings tree it names
(:meth:`PlannerConfig.to_settings`, :class:`~stalm.settings.tree.RunSettings`), which holds
every setting and is what the planners are built from. Both are plain, picklable data (they
cross process and Ray boundaries); the language-model backend is made from the tree inside the
process that plans (:func:`llm_backend`), because a loaded model cannot be shipped. These
types sit below every planner module and the registry, so a planner imports them from here and
the registry imports the planners: imports go one way.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from stalm.llm.backends.base import LLMBackend
from stalm.llm.prompt import PromptOptions
from stalm.progress import Progress as Progress  # where a planner reports what it is doing
from stalm.settings.io import with_values
from stalm.settings.tree import FLAT_NAMES, RunSettings

_TREE = RunSettings()
"""The settings tree's defaults, which :class:`PlannerConfig`'s fields take as theirs."""


@dataclass(frozen=True)
class PlannerConfig:
    """The usual choices about a planner, flat; ``None`` means the planner's paper default.
    Each field is one key of the settings tree (:data:`~stalm.settings.tree.FLAT_NAMES`;
    ``prompt`` is its ``prompt`` section), with the tree's default, read from the tree; the
    tree's sections check the values (:meth:`to_settings`)."""

    llm: str | None = _TREE.llm.backend
    """Backend spec as ``--llm`` takes it (None: $STALM_LLM or the embedded model)."""
    proposer: str = _TREE.proposer.kind
    """Where STaLM's task plans come from: 'llm', 'symbolic' or 'noisy' (the tree's
    ``proposer.noise`` section configures the noisy one)."""
    sims: int | None = _TREE.search.sims
    """N_budget; None gives the planner's default (30 for STaLM, 35 for the UCT baselines)."""
    batch: int = _TREE.search.batch
    """N_batch: replies per query."""
    constrained: bool | None = _TREE.llm.constrained
    """Grammar-constrained replies; None: on for the embedded model only."""
    prompt: PromptOptions = _TREE.prompt
    cache_mode: str = _TREE.llm.cache
    """Reply cache: use, refresh, off or replay."""
    cache_file: str | None = _TREE.llm.cache_file
    """The reply cache's SQLite file (None: the default under $STALM_CACHE_DIR)."""
    feedback: bool | None = _TREE.execution.feedback
    """Geometric feedback to the proposer; None: on for the symbolic proposer, off for a
    language model (the paper's method; ``--feedback`` turns it on)."""
    reuse_tree: bool = _TREE.execution.reuse_tree
    """Keep the executed child's subtree between real steps (the authors' loop)."""
    execution: str = _TREE.execution.rule
    """What an online tree planner executes without a goal plan: 'progress' (search on
    while nothing promises progress) or 'best_q' (the authors' rule)."""
    kappa_tries: int = _TREE.execution.kappa_tries
    """κ draws per task-plan step in Concretize: the authors' 3 (Algorithm 2 draws 1; with
    one, OPEN's single try fails a third of the task plans at their first step)."""
    backtracks: int | None = _TREE.execution.backtracks
    """Concretize re-draws a placement whose object blocks a later step at most this many
    times per plan; None: 6 with geometric feedback, 0 without (Algorithm 2)."""
    goal_atom_lost: float = _TREE.rewards.goal_atom_lost
    """Reward taken back when an action makes a goal conjunct false (0: the authors')."""
    goal_relations_only: bool = _TREE.proposer.goal_relations_only
    """The symbolic proposer grounds relative placements only for the goal's relations."""

    def __post_init__(self) -> None:
        self.to_settings()  # the tree's sections check every value

    def to_settings(self) -> RunSettings:
        """The settings tree these flat choices name (everything else at its default)."""
        values = [
            (FLAT_NAMES[f.name], getattr(self, f.name))
            for f in fields(self)
            if f.name in FLAT_NAMES
        ]
        return replace(with_values(RunSettings(), values, "PlannerConfig"), prompt=self.prompt)

    @classmethod
    def from_settings(cls, settings: RunSettings) -> PlannerConfig:
        """The flat choices of a tree (what the tree holds beyond them is dropped)."""
        values = {
            name: getattr(getattr(settings, path.split(".")[0]), path.split(".")[1])
            for name, path in FLAT_NAMES.items()
        }
        return cls(prompt=settings.prompt, **values)


def llm_backend(settings: RunSettings) -> LLMBackend:
    """The configured backend behind the reply cache; for a backend a re-run record named
    (``llm.from_record``), only its cached replies."""
    from stalm.llm.backends import make_backend
    from stalm.llm.cache import CachedBackend
    from stalm.llm.cache_file import ReplyCache

    llm = settings.llm
    replay = llm.cache == "replay" or llm.from_record  # replay only reads the file
    cache = None if llm.cache_file is None else ReplyCache(llm.cache_file, read_only=replay)
    if llm.from_record:  # a server only a record names is never asked: replay its cache
        from stalm.llm.backends.identity import CacheOnlyBackend, spec_identity

        replay_only = CacheOnlyBackend(spec_identity(llm.backend))
        return CachedBackend(replay_only, cache, mode="replay", legacy=False)
    return CachedBackend(make_backend(llm.backend), cache, mode=llm.cache)


def use_constraint(settings: RunSettings, backend: LLMBackend) -> bool:
    """The embedded model rarely writes a parseable plan unconstrained; servers are free."""
    constrained = settings.llm.constrained
    return backend.name == "embedded" if constrained is None else constrained
