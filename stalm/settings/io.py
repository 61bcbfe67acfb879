"""The settings tree as text: dotted overrides, settings files, records and YAML.

A tree (:class:`~stalm.settings.tree.RunSettings`) is built from its defaults, then a
file (``--settings run.yaml``, YAML or JSON: sections of keys, or dotted keys), then
``--set KEY=VALUE`` overrides, each a dotted path (``search.c=30``) whose value is read as a
YAML scalar and checked against the dataclass field's type. A record's ``settings`` object
is read back the same way. Every mistake is one :class:`~stalm.errors.StalmError` line that
names where it came from and the key, and lists the keys that would have been valid.

The flat names of :data:`~stalm.settings.tree.FLAT_NAMES` (``--set execution=best_q``,
``--set reuse_tree=false``, as the commands of ``docs/results.md`` were written) still work.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import yaml

from stalm.errors import StalmError
from stalm.files import (
    MAX_PROBLEM_FILE_BYTES,
    excerpt,
    load_yaml,
    read_text,
    short_repr,
)
from stalm.settings.tree import FLAT_NAMES, RunSettings

NON_NEGATIVE = ("samplers", "predicates")
"""Sections of the layers' own dataclasses whose counts must not be negative (they check
nothing themselves), but for the keys of :data:`NOT_COUNTS`."""
NOT_COUNTS = ("predicates.seed", "predicates.workers")
"""``predicates.seed`` is any integer; ``predicates.workers`` is checked by its section, with
the words every count of processes is refused with (0 and -1 alike)."""


def _sections() -> dict[str, type]:
    return typing.get_type_hints(RunSettings)  # the sections by name, in field order


def _is_section(hint: Any) -> bool:
    """Whether a field holds a (sub)section -- a dataclass of settings -- rather than a value
    (``proposer.noise`` is a section inside the section ``proposer``)."""
    return isinstance(hint, type) and dataclasses.is_dataclass(hint)


def _leaves(prefix: str, cls: type) -> list[str]:
    """The dotted keys of every value below section ``cls`` at ``prefix``, in field order."""
    hints = typing.get_type_hints(cls)
    keys: list[str] = []
    for f in dataclasses.fields(cls):
        key = f"{prefix}.{f.name}"
        keys += _leaves(key, hints[f.name]) if _is_section(hints[f.name]) else [key]
    return keys


def setting_keys() -> list[str]:
    """Every dotted key of the tree, in the order ``--show-settings`` prints them."""
    return [key for section, cls in _sections().items() for key in _leaves(section, cls)]


def _walk(key: str, source: str) -> Any:
    """The value type or the (sub)section class at dotted ``key``; a StalmError listing the
    valid keys if there is none (an empty name names the section it is in)."""
    sections = _sections()
    section, *names = key.split(".")
    shown = key if len(key) <= 80 and key.isprintable() else excerpt(key, 80)
    if section not in sections:
        raise StalmError(
            f"{source}: unknown setting '{shown}' (sections: {', '.join(sections)}; "
            f"e.g. search.c; `stalm solve P1 --show-settings` lists every key)"
        )
    node, path = sections[section], section
    for name in names:
        if not _is_section(node):
            raise StalmError(f"{source}: unknown setting '{shown}' ({path} is a value)")
        fields = [f.name for f in dataclasses.fields(node)]
        if name not in fields:
            valid = ", ".join(f"{path}.{f}" for f in fields)
            what = f"'{path}' is a section" if not name else f"unknown setting '{shown}'"
            raise StalmError(f"{source}: {what} (valid: {valid})")
        node, path = typing.get_type_hints(node)[name], f"{path}.{name}"
    return node


def _field_type(key: str, source: str) -> Any:
    """The type of the value at dotted ``key`` (see :func:`_walk`; a section is no value)."""
    hint = _walk(key, source)
    if _is_section(hint):
        valid = ", ".join(f"{key}.{f.name}" for f in dataclasses.fields(hint))
        raise StalmError(f"{source}: '{key}' is a section (valid: {valid})")
    return hint


def _describe(hint: Any) -> str:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is Literal:
        return "one of " + ", ".join(str(a) for a in args)
    if origin in (types.UnionType, typing.Union):
        return " or ".join(_describe(a) for a in args if a is not type(None)) + " or null"
    if origin is tuple:
        return f"a list of {len(args)} numbers"
    return {bool: "true or false", int: "an integer", float: "a number", str: "a string"}.get(
        hint, str(hint)
    )


def _coerce(value: Any, hint: Any) -> Any:
    """``value`` as the field type ``hint`` wants it; ValueError if it is not one."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        if value is None and type(None) in args:
            return None
        for option in (a for a in args if a is not type(None)):
            try:
                return _coerce(value, option)
            except ValueError:
                continue
        raise ValueError(value)
    if origin is Literal:
        if value in args:
            return value
        raise ValueError(value)
    if origin is tuple:
        if not isinstance(value, list | tuple) or len(value) != len(args):
            raise ValueError(value)
        return tuple(_coerce(v, a) for v, a in zip(value, args, strict=True))
    if hint is float and isinstance(value, str):  # PyYAML reads 1e3 (no dot) as a string
        try:
            value = float(value)
        except ValueError:
            raise ValueError(value) from None
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if hint is bool and isinstance(value, bool):
        return value
    if hint is int and number and isinstance(value, int):
        return value
    if hint is float and number and math.isfinite(value):
        return float(value)
    if hint is str and isinstance(value, str):
        return value
    raise ValueError(value)


def _checked(key: str, value: Any, source: str) -> Any:
    hint = _field_type(key, source)
    try:
        coerced = _coerce(value, hint)
    except ValueError:
        raise StalmError(
            f"{source}: {key} must be {_describe(hint)}, got {short_repr(value)}"
        ) from None
    counted = key.partition(".")[0] in NON_NEGATIVE and key not in NOT_COUNTS
    if counted and isinstance(coerced, int) and coerced < 0:
        raise StalmError(f"{source}: {key} must be an integer >= 0, got {coerced!r}")
    return coerced


def _replaced(part: Any, names: list[str], value: Any) -> Any:
    """Section ``part`` with the value at the dotted path ``names`` below it replaced (the
    sections on the way rebuilt, so each checks itself again)."""
    name = names[0]
    if len(names) > 1:
        value = _replaced(getattr(part, name), names[1:], value)
    return dataclasses.replace(part, **{name: value})


def with_values(
    settings: RunSettings, values: Iterable[tuple[str, Any]], source: str
) -> RunSettings:
    """``settings`` with each (dotted key, value) set, checked by key and type in order."""
    for key, value in values:
        key = FLAT_NAMES.get(key, key)
        coerced = _checked(key, value, source)
        section, *names = key.split(".")
        part = getattr(settings, section)
        try:
            settings = dataclasses.replace(settings, **{section: _replaced(part, names, coerced)})
        except StalmError as error:
            raise StalmError(f"{source}: {error}") from None
    return settings


def parse_override(pair: str) -> tuple[str, Any]:
    """``KEY=VALUE`` as (key, value read as a YAML scalar); a StalmError if not that form."""
    key, sep, text = pair.partition("=")
    key = key.strip()
    if not sep or not key:
        raise StalmError(f"--set {pair}: expected KEY=VALUE, e.g. search.c=30")
    try:
        value = yaml.safe_load(text) if text.strip() else None
    except yaml.YAMLError:
        value = text.strip()  # not YAML: the text itself (a type check follows)
    return key.replace("-", "_"), value


def with_overrides(settings: RunSettings, pairs: Sequence[str]) -> RunSettings:
    """``settings`` with ``--set KEY=VALUE`` overrides, applied in order."""
    for pair in pairs:
        settings = with_values(settings, [parse_override(pair)], f"--set {pair}")
    return settings


def flatten(data: Mapping[str, Any], source: str) -> list[tuple[str, Any]]:
    """(dotted key, value) pairs of a nested mapping of sections (dotted keys allowed, and the
    flat names); a value that is a mapping must be a section's (or a subsection's, such as
    ``proposer: {noise: {rate: 0.25}}``)."""
    pairs: list[tuple[str, Any]] = []
    for key, value in data.items():
        key = str(key)
        if isinstance(value, Mapping):
            if not _is_section(_walk(key, source)):  # raises for an unknown key
                raise StalmError(f"{source}: {key} is a setting, not a section")
            pairs += flatten({f"{key}.{name}": inner for name, inner in value.items()}, source)
        else:
            pairs.append((key, value))
    return pairs


def from_mapping(data: Any, source: str, base: RunSettings | None = None) -> RunSettings:
    """``base`` (default: the defaults) with the settings of a mapping (a file, a record)."""
    if not isinstance(data, Mapping):
        raise StalmError(
            f"{source}: settings must be a mapping of sections, got {short_repr(data)}"
        )
    return with_values(base or RunSettings(), flatten(data, source), source)


def read_settings_file(path: Path) -> Any:
    """The data of a YAML or JSON settings file (``--settings``), with the problem files'
    guards (:mod:`stalm.files`): a regular file of at most
    :data:`~stalm.files.MAX_PROBLEM_FILE_BYTES`, a safe loader, and a bound on the values its
    aliases stand for (500 bytes of nested aliases hung the old reader for minutes)."""
    text = read_text(path, MAX_PROBLEM_FILE_BYTES, "settings file")
    return load_yaml(text, f"--settings {path}") or {}


def with_file(settings: RunSettings, path: Path, data: Any = None) -> RunSettings:
    """``settings`` with those of a YAML or JSON file (``--settings``); ``data``: the file's
    data when the caller has read it already (:func:`read_settings_file`)."""
    if data is None:
        data = read_settings_file(path)
    return from_mapping(data, f"--settings {path}", settings)


def _plain(value: Any) -> Any:
    """A setting's value as plain JSON/YAML data: a section as a mapping, a tuple as a list."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    return list(value) if isinstance(value, tuple) else value


def to_dict(settings: RunSettings) -> dict[str, dict[str, Any]]:
    """The tree as plain JSON/YAML data (sections as mappings, tuples as lists)."""
    return {section: _plain(getattr(settings, section)) for section in _sections()}


def dotted(data: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested sections as one mapping of dotted keys to values (a record's settings too)."""
    flat: dict[str, Any] = {}
    for name, value in data.items():
        key = f"{prefix}{name}"
        if isinstance(value, Mapping):
            flat |= dotted(value, f"{key}.")
        else:
            flat[key] = value
    return flat


def changed(settings: RunSettings, base: RunSettings | None = None) -> dict[str, Any]:
    """The dotted keys whose values differ from ``base`` (default: the defaults)."""
    ours, theirs = dotted(to_dict(settings)), dotted(to_dict(base or RunSettings()))
    return {key: value for key, value in ours.items() if value != theirs[key]}


class _Dumper(yaml.SafeDumper):
    """Block style for the sections, flow style for a list (a range reads as [lo, hi])."""


_Dumper.add_representer(
    list, lambda dumper, data: dumper.represent_sequence("tag:yaml.org,2002:seq", data, True)
)


def to_yaml(settings: RunSettings) -> str:
    """The tree as YAML, sections in order (what ``--show-settings`` prints)."""
    return yaml.dump(to_dict(settings), Dumper=_Dumper, sort_keys=False)
