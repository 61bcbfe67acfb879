"""The one name for a JSON object whose shape is not this package's to type.

A record's typed parts (frozen dataclasses) say what they hold; where they meet a file they
become plain JSON (``to_json``), and a reader gets plain JSON from a file before it has checked
what is there (a record is untrusted input, possibly written by an older stalm). Those two
boundaries, and only they, hold a :data:`JsonObject`.
"""

from __future__ import annotations

from typing import Any

JsonObject = dict[str, Any]
"""A JSON object as :func:`json.loads` returns it and :func:`json.dumps` takes it."""
