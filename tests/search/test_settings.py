"""SearchSettings: the paper's defaults, and errors that name the bad field."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from stalm.errors import StalmError
from stalm.search.settings import SearchSettings


def test_defaults_are_the_papers() -> None:
    settings = SearchSettings()
    assert (settings.c, settings.k, settings.alpha) == (50.0, 1.5, 0.15)
    assert (settings.gamma, settings.horizon, settings.budget) == (0.99, 20, 30)


def test_settings_are_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        SearchSettings().c = 1.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("field", "value"),
    [("c", -1.0), ("k", 0.0), ("alpha", 1.0), ("gamma", 0.0), ("horizon", 0), ("budget", -1)],
)
def test_bad_values_name_the_field(field: str, value: float) -> None:
    with pytest.raises(StalmError, match=f"'{field}'"):
        changes: dict[str, Any] = {field: value}
        SearchSettings(**changes)
