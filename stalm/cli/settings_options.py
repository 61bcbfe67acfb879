"""The settings tree from a command line: defaults, ``--settings FILE``, flags, ``--set``.

``stalm solve`` and ``stalm experiment`` build their :class:`~stalm.settings.tree.
RunSettings` here, in one order: the defaults, then the file, then the command's own flags
(``--sims``, ``--batch``, ``--llm``, ...; each is an override of one key, applied only when
given), then every ``--set KEY=VALUE`` in the order written. So ``--set`` wins over a flag,
and a flag over the file.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the tree's modules load the domain: imported when a command runs
    from stalm.settings.tree import RunSettings

SETTINGS_HELP = (
    "A YAML or JSON file of settings (sections of keys, as --show-settings prints them); "
    "flags and --set override it."
)
SET_HELP = (
    "Setting KEY=VALUE, repeatable, applied last: a dotted key of the settings tree (e.g. "
    "search.c=30, execution.rule=best_q, rewards.goal_atom_lost=0, budget.horizon=10; "
    "`stalm solve P1 --show-settings` lists them all), the value read as YAML."
)


@dataclass(frozen=True)
class CommandSettings:
    """A command's settings tree and the keys its file, flags and ``--set`` named."""

    settings: RunSettings
    named: frozenset[str]
    """Dotted keys given explicitly (a command's own default may fill the others)."""


def command_settings(
    file: Path | None,
    flags: Sequence[tuple[str, str, Any]],
    overrides: Sequence[str],
) -> CommandSettings:
    """The tree of one command: defaults, ``file``, then ``flags`` -- (option, dotted key,
    value) of each flag given -- then ``overrides`` (``--set``)."""
    from stalm.settings.io import (
        flatten,
        parse_override,
        read_settings_file,
        with_file,
        with_values,
    )
    from stalm.settings.tree import FLAT_NAMES, RunSettings

    named: set[str] = set()
    settings = RunSettings()
    if file is not None:
        data = read_settings_file(file)  # read once, with the problem files' guards
        settings = with_file(settings, file, data)
        named |= {FLAT_NAMES.get(key, key) for key, _ in flatten(data, f"--settings {file}")}
    for option, key, value in flags:
        settings = with_values(settings, [(key, value)], option)
        named.add(key)
    for pair in overrides:
        key, value = parse_override(pair)
        settings = with_values(settings, [(key, value)], f"--set {pair}")
        named.add(FLAT_NAMES.get(key, key))
    return CommandSettings(settings, frozenset(named))


def given(**options: tuple[str, Any]) -> list[tuple[str, str, Any]]:
    """The (option, key, value) of each flag whose value is not None, named by keyword:
    ``given(sims=("search.sims", 5))`` is ``[("--sims", "search.sims", 5)]``."""
    return [
        (f"--{name.replace('_', '-')}", key, value)
        for name, (key, value) in options.items()
        if value is not None
    ]
