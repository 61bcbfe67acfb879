"""A reply cache that cannot be written still replays (issue 30, item 8).

Replay only reads, so it opens the cache file read-only: a cache someone sent on a read-only
medium, or in a folder the user may not write, replays as it is, and is left unchanged.
"""

from __future__ import annotations

import dataclasses
import sqlite3
from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.llm.cache import CachedBackend
from stalm.llm.cache_file import ReplyCache, sample_key
from stalm.settings.io import with_values
from stalm.settings.tree import RunSettings
from tests.read_only import read_only

from .llm_doubles import CountingFakeBackend, FailingFakeBackend
from .test_llm_cache import OLD_SCHEMA, REQUEST

pytestmark = pytest.mark.usefixtures("clean_llm_env")


def _recorded(folder: Path) -> tuple[Path, tuple[object, ...]]:
    """A cache file in ``folder`` holding the replies to REQUEST, and those replies."""
    folder.mkdir(parents=True, exist_ok=True)
    cache = ReplyCache(folder / "replies.sqlite")
    replies = CachedBackend(CountingFakeBackend(), cache).complete(REQUEST).replies
    assert not any(folder.glob("*-wal"))  # the last close folded the log into the file
    return cache.path, replies


def test_replay_reads_the_default_cache_in_a_read_only_folder(clean_llm_env: Path) -> None:
    path, replies = _recorded(clean_llm_env)
    before = path.read_bytes()
    with read_only(path, clean_llm_env):
        replay = CachedBackend(FailingFakeBackend(), mode="replay")
        response = replay.complete(REQUEST)
        assert response.from_cache and response.replies == replies
        with pytest.raises(StalmError, match="lacks 2 of 5 samples"):
            replay.complete(dataclasses.replace(REQUEST, n=5))
    assert path.read_bytes() == before
    assert sorted(p.name for p in clean_llm_env.iterdir()) == ["replies.sqlite"]


def test_replay_reads_a_named_read_only_cache_file(tmp_path: Path) -> None:
    """``--cache replay --set llm.cache_file=FILE``: the settings' path, opened read-only."""
    from stalm.proposers.model_backend import llm_backend

    path, replies = _recorded(tmp_path / "sent")
    values = {"llm.cache": "replay", "llm.cache_file": str(path), "llm.backend": "embedded"}
    settings = with_values(RunSettings(), values.items(), "test")
    with read_only(path, path.parent):
        backend = llm_backend(settings)
        assert isinstance(backend, CachedBackend) and backend.cache is not None
        keys = [sample_key("fake", "fake-model", REQUEST, i) for i in range(REQUEST.n)]
        stored = backend.cache.get_many(keys)
        assert [stored[key] for key in keys] == list(replies)


def test_a_read_only_cache_from_before_call_seconds_replays(tmp_path: Path) -> None:
    old = tmp_path / "old" / "replies.sqlite"
    old.parent.mkdir()
    with sqlite3.connect(old) as conn:
        conn.executescript(OLD_SCHEMA)
    with read_only(old, old.parent):
        found = ReplyCache(old, read_only=True).get_stored(["k1", "k2"])
    assert list(found) == ["k1"] and found["k1"].call_seconds == 2.5


def test_replaying_a_missing_cache_is_one_line(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere" / "replies.sqlite"
    with pytest.raises(StalmError, match=r"no reply cache to replay at .*nowhere"):
        ReplyCache(missing, read_only=True)
    assert not missing.parent.exists()
