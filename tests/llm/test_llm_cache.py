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
from stalm.llm.cache import CachedBackend, check_cache_mode
from stalm.llm.cache_file import ReplyCache, default_cache_path, sample_key
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


class SleepingFakeBackend(CountingFakeBackend):
    """A fake backend whose every call takes ``seconds`` of wall time, as a real model does."""

    def __init__(self, seconds: float) -> None:
        super().__init__()
        self.seconds = seconds

    def complete(self, request):  # type: ignore[no-untyped-def]
        import time

        time.sleep(self.seconds)
        return super().complete(request)


def test_cached_replies_carry_the_seconds_their_call_took(cache: ReplyCache) -> None:
    inner = SleepingFakeBackend(0.3)
    backend = CachedBackend(inner, cache, mode="use")
    first = backend.complete(REQUEST)
    assert (first.from_cache, first.cached_replies, first.cached_seconds) == (False, 0, 0.0)
    keys = [sample_key("fake", "fake-model", REQUEST, i) for i in range(3)]
    stored = cache.get_stored(keys)
    # each of the call's three replies is stored with a third of the call's time
    shares = [stored[key].call_seconds for key in keys]
    assert shares[0] == shares[1] == shares[2] and 0.1 <= shares[0] < 0.2
    again = backend.complete(REQUEST)
    assert again.from_cache and again.cached_replies == 3 and len(inner.requests) == 1
    assert again.cached_seconds == pytest.approx(sum(shares)) and again.cached_seconds >= 0.3
    # a batch extended later: two cached replies at their stored seconds, two made now
    bigger = backend.complete(dataclasses.replace(REQUEST, n=5))
    assert not bigger.from_cache and bigger.cached_replies == 3
    assert bigger.cached_seconds == pytest.approx(sum(shares))


OLD_SCHEMA = """
CREATE TABLE meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE prompts (prompt_sha TEXT PRIMARY KEY, system TEXT NOT NULL, user TEXT NOT NULL);
CREATE TABLE replies (
    key TEXT PRIMARY KEY, backend TEXT NOT NULL, model TEXT NOT NULL, prompt_sha TEXT NOT NULL,
    temperature REAL NOT NULL, max_tokens INTEGER NOT NULL, seed INTEGER,
    constraint_fingerprint TEXT, sample_index INTEGER NOT NULL, text TEXT NOT NULL,
    prompt_tokens INTEGER NOT NULL, completion_tokens INTEGER NOT NULL, latency_s REAL NOT NULL,
    finish_reason TEXT, created_at REAL NOT NULL
);
INSERT INTO replies VALUES ('k1', 'fake', 'm', 'sha', 1.0, 64, 5, NULL, 0, 'old reply',
    10, 5, 2.5, 'stop', 0.0);
"""


def test_a_cache_file_from_before_call_seconds_is_upgraded_and_merged(tmp_path: Path) -> None:
    old = tmp_path / "old.sqlite"
    with sqlite3.connect(old) as conn:
        conn.executescript(OLD_SCHEMA)
    copy = tmp_path / "copy.sqlite"
    shutil.copy(old, copy)
    # merged into a new cache as it is (the source file is not changed)
    home = ReplyCache(tmp_path / "home.sqlite")
    assert home.merge_from(copy) == 1
    # opened as a cache, it gains the column; its old rows fall back to their latency
    upgraded = ReplyCache(old)
    for found in (upgraded.get_stored(["k1"]), home.get_stored(["k1"])):
        assert found["k1"].reply.text == "old reply" and found["k1"].call_seconds == 2.5
    with sqlite3.connect(copy) as conn:
        columns = {row[1] for row in conn.execute("PRAGMA table_info(replies)")}
    assert "call_seconds" not in columns
