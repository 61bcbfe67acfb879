"""An on-disk reply cache, so an experiment re-run or a colleague's replay costs no model calls.

Language-model calls are the slowest and (for hosted models) the only paid part of a run, and
their samples are not reproducible across providers or versions. Caching every reply keyed by
*everything that determines its distribution* makes reruns cheap and lets a result be replayed
exactly from a cache file someone sends along.

One entry is one sample. Its key hashes the backend's identity (its provider and server: a
server that calls its model ``gpt-4-turbo-2024-04-09`` is not OpenAI), the model, the full
system and user prompt, the sampling settings (temperature, max_tokens, seed, constraint
fingerprint) and the sample's index in the batch. Keying by index rather than by batch means
asking for 5 samples after 3 were cached runs the model for the 2 missing ones only. The seed
is part of the key on purpose: trials with different seeds must get different draws, not one
shared cached batch.
Nothing else machine-specific (paths, user) enters the key, so a file copied to another machine
hits there too for the same server.

Entries an older stalm wrote were keyed by the backend's name (``openai-compatible``) and the
model only, so they do not say which server answered. They are served only to a backend the
user named (``legacy=True``, every command but a rerun that replays the model its record
names), each time with a one-line notice naming the backend they are served as.

The file, its keys and its schema are :mod:`stalm.llm.cache_file`; this module is the policy:
the modes, which samples to ask the model for, and what a served reply counts as having cost.

Each entry also keeps ``call_seconds``: its share of the wall time of the backend call that
produced it (the call's seconds divided by the replies it returned). A reply served from the
cache costs almost nothing now, but an experiment must not report a trial as fast (or as
solved within its budget) because an earlier arm happened to make the same call: planners
count a cached reply at its stored seconds (:attr:`LLMResponse.cached_seconds`). Entries
written before the column existed have no such share; their ``latency_s`` stands in (exact for
the embedded model, whose latency is per sample; for a batched server call it is the whole
call's time, an over-count).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable
from typing import Literal, cast, get_args

from stalm.errors import StalmError
from stalm.llm.backends.base import LLMBackend, LLMReply, LLMRequest, LLMResponse
from stalm.llm.backends.identity import identity_of
from stalm.llm.cache_file import (
    CachedSample,
    ReplyCache,
    StoredReply,
    legacy_sample_key,
    prompt_digest,
    sample_key,
)

CacheMode = Literal["use", "refresh", "off", "replay"]
"""``use``: read hits, run and store misses. ``refresh``: ignore stored replies, run the model
and overwrite them. ``off``: neither read nor write. ``replay``: read only, and a miss is an
error, which proves a result was reproduced from the cache file alone."""

CACHE_MODES: tuple[str, ...] = get_args(CacheMode)


def check_cache_mode(mode: str) -> CacheMode:
    """``mode`` as a :data:`CacheMode`, or a StalmError listing the valid ones."""
    if mode not in CACHE_MODES:
        raise StalmError(f"unknown cache mode {mode!r}; expected one of {', '.join(CACHE_MODES)}")
    return cast(CacheMode, mode)


class CachedBackend:
    """A backend that answers from a :class:`ReplyCache` and asks ``inner`` only for misses.

    It looks like its inner backend (same ``name``, ``model`` and ``description``), so wrapping
    changes nothing but cost. Missing sample indices are requested in contiguous runs with the
    run's first index as seed offset, so a cached batch extended later is the batch the model
    would have produced in one go (sample ``i`` always uses ``seed + i``). Replies served
    from the cache keep the token counts and latency of the call that produced them (what the
    result would have cost); ``from_cache`` tells that nothing was spent now, and
    ``cached_seconds`` what the served replies took when they were made. Each call made now
    is timed, and every reply it returned is stored with its share of that time.

    ``legacy`` serves entries an older stalm wrote without a server (see the module
    docstring), saying so once through ``notify`` (default: a line on stderr).
    """

    def __init__(
        self,
        inner: LLMBackend,
        cache: ReplyCache | None = None,
        mode: CacheMode | str = "use",
        *,
        legacy: bool = True,
        notify: Callable[[str], None] | None = None,
    ) -> None:
        self._inner = inner
        self._mode = check_cache_mode(mode)
        if cache is None and self._mode != "off":
            # replay only reads: a cache nobody may write still replays
            cache = ReplyCache(read_only=self._mode == "replay")
        self._cache = cache
        self._legacy = legacy
        self._notify = notify or _to_stderr
        self._legacy_said = False

    @property
    def identity(self) -> str:
        return identity_of(self._inner)

    @property
    def name(self) -> str:
        return self._inner.name

    @property
    def model(self) -> str:
        return self._inner.model

    @property
    def description(self) -> str:
        return self._inner.description

    @property
    def inner(self) -> LLMBackend:
        return self._inner

    @property
    def mode(self) -> CacheMode:
        return self._mode

    @property
    def cache(self) -> ReplyCache | None:
        return self._cache

    def complete(self, request: LLMRequest) -> LLMResponse:
        if self._mode == "off" or self._cache is None:
            return self._inner.complete(request)
        backend, model, identity = self._inner.name, self._inner.model, self.identity
        keys = [sample_key(identity, model, request, i) for i in range(request.n)]
        stored = self._cache.get_stored(keys) if self._mode in ("use", "replay") else {}
        hits = [stored.get(key) for key in keys]
        if self._legacy and self._mode in ("use", "replay") and None in hits:
            hits = self._with_legacy(hits, request)
        replies: list[LLMReply | None] = [hit.reply if hit else None for hit in hits]
        cached_seconds = sum(hit.call_seconds for hit in hits if hit is not None)
        missing = [i for i, reply in enumerate(replies) if reply is None]
        if missing and self._mode == "replay":
            raise StalmError(
                f"reply cache {self._cache.path} lacks {len(missing)} of {request.n} samples "
                f"for model {model!r} of {identity} (prompt "
                f"{prompt_digest(request.system, request.user)[:12]}, seed {request.seed}); "
                "replay mode runs no model (name one with --llm and --cache use to ask it)"
            )
        new_samples = []
        for start, length in _contiguous_runs(missing):
            sub_request = dataclasses.replace(request, n=length, seed=request.sample_seed(start))
            started = time.perf_counter()
            response = self._inner.complete(sub_request)
            share = (time.perf_counter() - started) / max(1, len(response.replies))
            # with a deadline, a backend stops short rather than outlast it (also when a retry's
            # backoff would): fewer replies are then the deadline's doing, not a broken backend
            cut_short = request.deadline is not None and (
                time.monotonic() >= request.deadline or len(response.replies) < length
            )
            if len(response.replies) != length and not cut_short:
                raise StalmError(
                    f"backend {backend!r} (model {model!r}) returned {len(response.replies)} "
                    f"replies for {length} requested"
                )
            for offset, reply in enumerate(response.replies):
                index = start + offset
                replies[index] = reply
                if reply.finish_reason != "deadline":  # a cut reply is not the model's answer
                    new_samples.append(
                        CachedSample(
                            keys[index], backend, model, request, index, reply, share, identity
                        )
                    )
            if cut_short:
                break
        self._cache.put_many(new_samples)
        return LLMResponse(
            replies=tuple(reply for reply in replies if reply is not None),
            backend=backend,
            model=model,
            from_cache=not missing,
            cached_replies=request.n - len(missing),
            cached_seconds=cached_seconds,
        )

    def _with_legacy(
        self, hits: list[StoredReply | None], request: LLMRequest
    ) -> list[StoredReply | None]:
        """``hits`` with the misses an older stalm's entry answers (keyed by the backend's
        name, not its server), said once."""
        assert self._cache is not None
        name, model = self._inner.name, self._inner.model
        keys = {i: legacy_sample_key(name, model, request, i) for i, h in enumerate(hits) if not h}
        found = self._cache.get_stored(keys.values())
        if not found:
            return hits
        if not self._legacy_said:
            self._legacy_said = True
            self._notify(
                f"replies cached by an older stalm, which did not record which server made "
                f"them, are served as model {model!r} of {self.identity}'s (from "
                f"{self._cache.path}; --cache refresh asks the model again)"
            )
        return [found.get(keys[i]) if hit is None else hit for i, hit in enumerate(hits)]


def _to_stderr(message: str) -> None:
    print(f"note: {message}", file=sys.stderr)


def _contiguous_runs(indices: list[int]) -> list[tuple[int, int]]:
    """``[0, 1, 3]`` -> ``[(0, 2), (3, 1)]``: (start, length) of each run of sorted indices."""
    runs: list[tuple[int, int]] = []
    for index in indices:
        if runs and runs[-1][0] + runs[-1][1] == index:
            runs[-1] = (runs[-1][0], runs[-1][1] + 1)
        else:
            runs.append((index, 1))
    return runs
