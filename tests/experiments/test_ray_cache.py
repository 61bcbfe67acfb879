"""Replies made on Ray workers come home: cache files travel as bytes and merge idempotently."""

from __future__ import annotations

from pathlib import Path

from stalm.experiments.ray_runner import merge_cache_bytes
from stalm.llm.backends.base import LLMReply, LLMRequest
from stalm.llm.cache_file import CachedSample, ReplyCache


def _sample(key: str, text: str) -> CachedSample:
    request = LLMRequest(system="system", user=f"user {key}", n=1, seed=3)
    return CachedSample(key, "embedded", "m", request, 0, LLMReply(text, 5, 7, 0.5, "stop"))


def test_worker_replies_merge_into_the_callers_cache_once(tmp_path: Path) -> None:
    home = ReplyCache(tmp_path / "home.sqlite")
    home.put_many([_sample("a", "kept")])
    worker = ReplyCache(tmp_path / "worker.sqlite")
    worker.put_many([_sample("a", "not overwritten"), _sample("b", "new")])
    data = worker.export(tmp_path / "export.sqlite").read_bytes()

    assert merge_cache_bytes(home, data) == 1
    assert merge_cache_bytes(home, data) == 0
    found = home.get_many(["a", "b"])
    assert found["a"].text == "kept"
    assert found["b"].text == "new"
    assert found["b"].completion_tokens == 7


def test_a_trial_without_model_calls_sends_no_cache_back(tmp_path: Path) -> None:
    from stalm.experiments.ray_runner import trial_with_cache_copy
    from stalm.experiments.suites import build_plan, trial_specs

    cache = ReplyCache(tmp_path / "home.sqlite")
    cache.put_many([_sample("a", "kept")])
    data = cache.export(tmp_path / "snapshot.sqlite").read_bytes()
    [spec] = trial_specs(
        build_plan("table2", planners=("uct",), problems=("P2",), trials=1, time_budget_s=1.0)
    )
    record, returned = trial_with_cache_copy(spec, data)
    assert returned is None
    assert record["key"] == spec.key  # the private cache path does not change the trial
    assert record["planner"] == "uct"
