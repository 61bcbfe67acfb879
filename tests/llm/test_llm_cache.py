"""The reply cache: what its keys depend on, its modes, extending a batch, replaying a copied
file, and several processes writing at once."""

from __future__ import annotations

import dataclasses
import multiprocessing
import shutil
import sqlite3
from pathlib import Path

import pytest

from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.backends import LLMBackend, LLMRequest
from stalm.llm.cache import (
    CachedBackend,
    ReplyCache,
    check_cache_mode,
    default_cache_path,
    sample_key,
)
from stalm.llm.constraints import build_constraint

from .llm_doubles import CountingFakeBackend, FailingFakeBackend

pytestmark = pytest.mark.usefixtures("clean_llm_env")

REQUEST = LLMRequest(system="sys", user="find a plan", n=3, temperature=1.0, max_tokens=64, seed=5)


@pytest.fixture
def cache(tmp_path: Path) -> ReplyCache:
    return ReplyCache(tmp_path / "replies.sqlite")


def test_default_path_follows_the_environment(clean_llm_env: Path) -> None:
    assert default_cache_path() == clean_llm_env / "replies.sqlite"
    assert ReplyCache().path == clean_llm_env / "replies.sqlite"


def test_key_depends_on_everything_that_shapes_the_sample() -> None:
    constraint = build_constraint(Vocabulary(("coke",), ("counter1",), ()))
    base = sample_key("fake", "m", REQUEST, 0)
    variants = [
        sample_key("other-backend", "m", REQUEST, 0),
        sample_key("fake", "other-model", REQUEST, 0),
        sample_key("fake", "m", REQUEST, 1),
        sample_key("fake", "m", dataclasses.replace(REQUEST, system="sys2"), 0),
        sample_key("fake", "m", dataclasses.replace(REQUEST, user="find a plan!"), 0),
        sample_key("fake", "m", dataclasses.replace(REQUEST, temperature=0.7), 0),
        sample_key("fake", "m", dataclasses.replace(REQUEST, max_tokens=65), 0),
        sample_key("fake", "m", dataclasses.replace(REQUEST, seed=6), 0),
        sample_key("fake", "m", dataclasses.replace(REQUEST, seed=None), 0),
        sample_key("fake", "m", dataclasses.replace(REQUEST, constraint=constraint), 0),
    ]
    assert base not in variants
    assert len(set(variants)) == len(variants)
    # The batch size is not part of the key: sample 0 of 3 is sample 0 of 5.
    assert sample_key("fake", "m", dataclasses.replace(REQUEST, n=5), 0) == base


def test_use_mode_serves_repeats_from_the_cache(cache: ReplyCache) -> None:
    inner = CountingFakeBackend()
    backend = CachedBackend(inner, cache, mode="use")
    assert isinstance(backend, LLMBackend)
    first = backend.complete(REQUEST)
    second = backend.complete(REQUEST)
    assert len(inner.requests) == 1
    assert not first.from_cache and second.from_cache
    assert first.replies == second.replies
    assert second.texts == (
        "find a plan|seed=5|t=1.0",
        "find a plan|seed=6|t=1.0",
        "find a plan|seed=7|t=1.0",
    )
    assert (backend.name, backend.model) == ("fake", "fake-model")
    assert len(cache) == 3


def test_a_larger_batch_asks_only_for_the_missing_samples(cache: ReplyCache) -> None:
    inner = CountingFakeBackend()
    backend = CachedBackend(inner, cache)
    backend.complete(REQUEST)
    bigger = backend.complete(dataclasses.replace(REQUEST, n=5))
    assert len(inner.requests) == 2
    extension = inner.requests[1]
    assert (extension.n, extension.seed) == (2, 8)
    assert bigger.texts[3:] == ("find a plan|seed=8|t=1.0", "find a plan|seed=9|t=1.0")
    assert not bigger.from_cache


def test_refresh_mode_reruns_and_overwrites(cache: ReplyCache) -> None:
    CachedBackend(CountingFakeBackend(model="m"), cache).complete(REQUEST)
    refreshed_inner = CountingFakeBackend(model="m")
    refresher = CachedBackend(refreshed_inner, cache, mode="refresh")
    refresher.complete(REQUEST)
    refresher.complete(REQUEST)
    assert len(refreshed_inner.requests) == 2
    assert len(cache) == 3  # overwritten, not duplicated


def test_off_mode_neither_reads_nor_writes(cache: ReplyCache) -> None:
    inner = CountingFakeBackend()
    backend = CachedBackend(inner, cache, mode="off")
    backend.complete(REQUEST)
    backend.complete(REQUEST)
    assert len(inner.requests) == 2
    assert len(cache) == 0


def test_replay_mode_never_runs_the_model(cache: ReplyCache) -> None:
    CachedBackend(CountingFakeBackend(), cache).complete(REQUEST)
    replay = CachedBackend(FailingFakeBackend(), cache, mode="replay")
    assert replay.complete(REQUEST).from_cache
    with pytest.raises(StalmError, match="lacks 2 of 5 samples"):
        replay.complete(dataclasses.replace(REQUEST, n=5))


def test_a_copied_cache_file_replays_on_another_machine(tmp_path: Path) -> None:
    original = ReplyCache(tmp_path / "mine" / "replies.sqlite")
    recorded = CachedBackend(CountingFakeBackend(), original).complete(REQUEST)
    sent = tmp_path / "theirs" / "replies.sqlite"
    sent.parent.mkdir()
    shutil.copyfile(original.path, sent)  # just the one file: no -wal file travels with it
    replayed = CachedBackend(FailingFakeBackend(), ReplyCache(sent), mode="replay")
    response = replayed.complete(REQUEST)
    assert response.from_cache and response.replies == recorded.replies


def test_export_makes_a_self_contained_copy(cache: ReplyCache, tmp_path: Path) -> None:
    CachedBackend(CountingFakeBackend(), cache).complete(REQUEST)
    exported = cache.export(tmp_path / "out" / "send-me.sqlite")
    assert len(ReplyCache(exported)) == 3
    with sqlite3.connect(exported) as conn:
        (system, user) = conn.execute("SELECT system, user FROM prompts").fetchone()
    assert (system, user) == ("sys", "find a plan")


def test_unknown_mode_is_a_user_error(cache: ReplyCache) -> None:
    with pytest.raises(StalmError, match="use, refresh, off, replay"):
        check_cache_mode("sometimes")
    with pytest.raises(StalmError):
        CachedBackend(CountingFakeBackend(), cache, mode="sometimes")


def test_unwritable_cache_location_is_a_user_error(tmp_path: Path) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    with pytest.raises(StalmError, match="cannot open the reply cache"):
        ReplyCache(blocker / "replies.sqlite")


def _write_many(path: str, worker: int) -> None:
    backend = CachedBackend(CountingFakeBackend(), ReplyCache(path))
    for i in range(40):
        backend.complete(LLMRequest(system="s", user=f"w{worker}-{i}", n=2, seed=i))


def test_several_processes_share_one_cache_file(tmp_path: Path) -> None:
    path = str(tmp_path / "shared.sqlite")
    ReplyCache(path)
    context = multiprocessing.get_context("fork")
    workers = [context.Process(target=_write_many, args=(path, w)) for w in range(3)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(timeout=60)
    assert [worker.exitcode for worker in workers] == [0, 0, 0]
    assert len(ReplyCache(path)) == 3 * 40 * 2
