"""Settings trees for tests, named by the flat names (``proposer``, ``sims``, ``llm``...) that
``--set`` and settings files still take (:data:`stalm.settings.tree.FLAT_NAMES`)."""

from __future__ import annotations

import dataclasses

from stalm.llm.prompt import PromptOptions
from stalm.settings.io import with_values
from stalm.settings.tree import RunSettings


def settings_of(**flat: object) -> RunSettings:
    """The default tree with each flat-named (or ``section__name``) choice set and checked;
    ``prompt`` takes a whole :class:`PromptOptions` section."""
    prompt = flat.pop("prompt", None)
    values = [(name.replace("__", "."), value) for name, value in flat.items()]
    settings = with_values(RunSettings(), values, "test settings")
    if prompt is not None:
        assert isinstance(prompt, PromptOptions)
        settings = dataclasses.replace(settings, prompt=prompt)
    return settings
