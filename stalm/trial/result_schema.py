"""Where the published schema of result records lies: ``result_schema.json`` beside this file.

A result record is what ``stalm solve --json`` writes and what ``stalm experiment`` appends
to a results log, one per line. Scripts read them, ``stalm view`` draws them and other tools
compare with them, so their shape is a contract: a JSON Schema (draft 2020-12) that the tests
check every committed record and a fresh solve against. Validating needs a JSON Schema
library (``jsonschema``), which stalm itself does not depend on.
"""

from __future__ import annotations

import json
from pathlib import Path

from stalm.json_object import JsonObject

SCHEMA_PATH = Path(__file__).with_name("result_schema.json")
"""The schema file, installed with the package."""


def result_schema() -> JsonObject:
    """The schema as a mapping, ready for a validator."""
    return json.loads(SCHEMA_PATH.read_text(encoding="utf-8"))
