"""The one name for a JSON object whose shape is not this package's to type, and the one way a
typed record becomes one.

A record's typed parts (frozen dataclasses) say what they hold; where they meet a file they
become plain JSON (:func:`record_json`, or a record's own ``to_json`` where its file shape is
not its fields), and a reader gets plain JSON from a file before it has checked what is there
(a record is untrusted input, possibly written by an older stalm). Those two boundaries, and
only they, hold a :data:`JsonObject`.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import fields, is_dataclass
from typing import Any, Protocol, runtime_checkable

JsonObject = dict[str, Any]
"""A JSON object as :func:`json.loads` returns it and :func:`json.dumps` takes it."""


@runtime_checkable
class WritesJson(Protocol):
    """A record whose file shape is its own (not its fields as they are)."""

    def to_json(self) -> JsonObject: ...


def record_json(record: object, omitted_when_none: Collection[str] = ()) -> JsonObject:
    """A dataclass record's fields as JSON, in field order: a nested record by its own
    ``to_json`` (else by this function), a tuple or list as a list; a field named in
    ``omitted_when_none`` is left out while it is None (others are written as null)."""
    return {
        f.name: json_value(getattr(record, f.name))
        for f in fields(record)  # type: ignore[arg-type]
        if not (f.name in omitted_when_none and getattr(record, f.name) is None)
    }


def json_value(value: object) -> object:
    """``value`` as JSON (see :func:`record_json`); a scalar or a mapping as it is."""
    if isinstance(value, WritesJson):
        return value.to_json()
    if is_dataclass(value) and not isinstance(value, type):
        return record_json(value)
    if isinstance(value, tuple | list):
        return [json_value(item) for item in value]
    return value
