"""Result records read back, whichever stalm wrote them: the one place an old record is
brought to today's shape.

``stalm replay``, ``view``, ``export`` and ``rerun`` read a record (``stalm solve --json``'s
object, or a line of a results log) through :func:`read_result` or :func:`read_record`, and the
results log's reader (:func:`stalm.experiments.results_log.read_records`, for resuming and
the report) hands on each record through :func:`upgraded`, so no reader downstream knows what
older versions wrote. What changed: the proposer's phase was named ``llm`` although Fast
Downward's runs were counted there too, so ``times.llm`` is read as ``times.proposer`` (where
both are present, ``proposer`` is kept).

Everything else an older record may lack (its problem's hash, the settings tree, the step
log) is not made up: each reader says what it cannot do without it.
"""

from __future__ import annotations

from pathlib import Path

from stalm.errors import StalmError
from stalm.files import MAX_RESULT_FILE_BYTES, load_json, read_text
from stalm.json_object import JsonObject

OLD_PHASE_NAMES = {"llm": "proposer"}
"""Phase keys records once wrote, by the name they have now."""


def upgraded(record: JsonObject) -> JsonObject:
    """``record`` in today's shape (see the module docstring); ``record`` itself when it is
    already, and never changed in place."""
    times = record.get("times")
    if not isinstance(times, dict) or not OLD_PHASE_NAMES.keys() & times.keys():
        return record
    renamed = {OLD_PHASE_NAMES.get(key, key): value for key, value in times.items()}
    renamed.update({key: value for key, value in times.items() if key not in OLD_PHASE_NAMES})
    return {**record, "times": renamed}


def read_result(path: Path) -> JsonObject:
    """The record of a result file (one JSON object, ``stalm solve --json``), upgraded; one
    StalmError naming the path when it is not one (too big, not JSON, not an object)."""
    data = load_json(read_text(path, MAX_RESULT_FILE_BYTES, "result file"), str(path), finite=True)
    if not isinstance(data, dict):
        raise StalmError(f"{path}: not a stalm result (not a JSON object)")
    return upgraded(data)


def read_record(path: Path, key: str | None) -> JsonObject:
    """The record in ``path``, upgraded: a JSON object, or the line of a JSON-lines file whose
    key starts with ``key`` (needed when the file holds more than one)."""
    text = read_text(path, MAX_RESULT_FILE_BYTES, "result file")  # regular, bounded
    try:
        records = [load_json(text, str(path), finite=True)]
    except StalmError:
        records = [
            load_json(line, f"{path}:{number}", finite=True)
            for number, line in enumerate(text.splitlines(), start=1)
            if line.strip()
        ]
    records = [r for r in records if isinstance(r, dict)]
    if key is not None:
        records = [r for r in records if str(r.get("key", "")).startswith(key)]
    if len(records) != 1:
        if not records:
            raise StalmError(
                f"{path}: no record" + (f" with a key starting {key!r}" if key else "")
            )
        sample = ", ".join(str(r.get("key", "?"))[:8] for r in records[:3])
        raise StalmError(f"{path}: {len(records)} records; choose one with --key (e.g. {sample})")
    return upgraded(records[0])
