"""Fixtures for the language-model tests: a problem vocabulary, a scripted server double,
and an environment cleared of a developer's LLM settings."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from stalm.domain.vocabulary import Vocabulary

from .llm_doubles import ScriptedHTTPServerDouble


@pytest.fixture
def p5_vocabulary() -> Vocabulary:
    """The names of the paper's P5 (Figure 13)."""
    return Vocabulary(
        movables=("coke", "sprite", "mango_juice", "dr_pepper", "pork_grill", "beef_grill"),
        regions=("counter1", "counter2", "counter3", "counter5"),
        doors=("kitchen_door",),
    )


@pytest.fixture
def scripted_server() -> Iterator[ScriptedHTTPServerDouble]:
    server = ScriptedHTTPServerDouble()
    server.start()
    yield server
    server.stop()


@pytest.fixture
def clean_llm_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """No developer's server, key or reply cache leaks into a test; returns the cache dir."""
    for name in (
        "STALM_LLM",
        "STALM_LLM_BASE_URL",
        "STALM_LLM_MODEL",
        "STALM_LLM_API_KEY",
        "STALM_LLM_CONSTRAINT_STYLE",
        "OPENAI_API_KEY",
        "OPENAI_BASE_URL",
    ):
        monkeypatch.delenv(name, raising=False)
    cache_dir = tmp_path / "stalm-cache"
    monkeypatch.setenv("STALM_CACHE_DIR", str(cache_dir))
    return cache_dir
