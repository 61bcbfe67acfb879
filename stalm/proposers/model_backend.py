"""The language-model backend a run's settings name, behind its reply cache.

Every planner that asks a model (STaLM with ``--proposer llm``, EP-SayCan, LLM-MCTS,
Iterative-Replanning) builds its backend here from the settings tree, inside the process that
plans: a loaded model cannot be shipped between processes, the settings (plain data) can.
"""

from __future__ import annotations

from stalm.llm.backends.base import LLMBackend
from stalm.settings.tree import RunSettings


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
