"""The problem inside a result record: written with the result, read back as a problem file is.

A result (``stalm solve --json``, a generated problem's witness) carries the validated problem
it was solved on: its name (``problem``), the spec itself as canonical data
(``problem_spec``: :meth:`ProblemSpec.model_dump` in JSON mode, the fields in the models'
order, so the same problem is written the same way byte for byte) and its hash
(``problem_hash``, :attr:`Problem.content_hash`). ``stalm replay``, ``view`` and ``rerun`` so
reopen a record on another machine, without the problem file.

A record is untrusted input (someone may send it): its embedded spec is bounded as a problem
file is (:data:`~stalm.files.MAX_PROBLEM_FILE_BYTES`), validated by the same models and guards
(:func:`~stalm.world.problem_file.parse_problem`, errors naming the record and the field), and
must hash to the record's ``problem_hash``, so a spec edited after the solve is refused.
A problem naming a file by a path relative to itself (its robot file, a mesh) is recorded
with the folder that path starts from (``problem_folder``), so its embedded copy finds the
same files from any working folder. ``--problem FILE`` overrides the embedded spec, checked
against the same hash. A record written before records carried their problem is found by
name, as it always was, and when that fails the error says to pass the problem file with
``--problem FILE``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from stalm.errors import StalmError
from stalm.files import MAX_PROBLEM_FILE_BYTES, excerpt
from stalm.world.problem import PROBLEM_HASH_FIELD, Problem, load_problem
from stalm.world.problem_file import parse_problem

PROBLEM_SPEC_FIELD = "problem_spec"
"""The field of a result that holds the problem it was solved on, as validated data."""
PROBLEM_FOLDER_FIELD = "problem_folder"
"""The field of a result that holds the folder (absolute) the embedded problem's relative
file paths (a robot file, a mesh) resolve against; written only for a problem that names a
file so, and not part of the problem's hash (moving the files keeps the problem the same)."""
MAX_FOLDER_CHARS = 4096
"""The longest ``problem_folder`` a record may give (a path, not a document)."""
RECORD_PROBLEM_HELP = (
    "The problem file (or name) to use instead of the one the record carries; its problem "
    "hash must be the record's."
)
"""The ``--problem`` help of the commands that reopen a record."""
_HASH_CHARS = 40
"""Characters of a record's (untrusted) hash quoted in an error."""


def problem_fields(problem: Problem) -> dict[str, Any]:
    """What a result records of its problem: the name, the hash, the spec itself and, if the
    spec names a file by a relative path, the folder that path starts from."""
    fields: dict[str, Any] = {
        "problem": problem.name,
        PROBLEM_HASH_FIELD: problem.content_hash,
        PROBLEM_SPEC_FIELD: problem.spec.model_dump(mode="json"),
    }
    folder = problem.spec.files_folder
    if folder is not None:
        fields[PROBLEM_FOLDER_FIELD] = str(folder)
    return fields


def embedded_problem(record: Mapping[str, object], source: str) -> Problem | None:
    """The problem ``record`` carries (None for a record written before records carried
    one), validated as a problem file; a StalmError naming ``source`` and the field if it is
    no valid problem or is not the one the record's hash names."""
    data = record.get(PROBLEM_SPEC_FIELD)
    if data is None:
        return None
    where = f"{source}: {PROBLEM_SPEC_FIELD}"
    size = len(json.dumps(data))  # a record was read bounded and finite: this cannot fail
    if size > MAX_PROBLEM_FILE_BYTES:
        raise StalmError(
            f"{where}: too long for a problem ({size} bytes; a problem file has at most "
            f"{MAX_PROBLEM_FILE_BYTES})"
        )
    folder = record.get(PROBLEM_FOLDER_FIELD)
    if folder is not None and not (isinstance(folder, str) and 0 < len(folder) <= MAX_FOLDER_CHARS):
        raise StalmError(
            f"{source}: {PROBLEM_FOLDER_FIELD}: not a folder's path (text of 1 to "
            f"{MAX_FOLDER_CHARS} characters)"
        )
    base = None if folder is None else Path(folder)
    problem = Problem(parse_problem(data, where, base=base), f"{source} (its embedded problem)")
    recorded = record.get(PROBLEM_HASH_FIELD)
    if recorded != problem.content_hash:
        raise StalmError(
            f"{where}: the problem is not the one the record's {PROBLEM_HASH_FIELD} names "
            f"({_quoted(recorded)} in the record, {problem.content_hash} for its spec): the "
            "record was changed after it was written; pass the problem file it was solved on "
            "with --problem FILE"
        )
    return problem


def record_problem(
    record: Mapping[str, object], source: str, given: str | None = None, folder: Path | None = None
) -> Problem:
    """The problem a record was solved on: ``given`` (``--problem``, a name or a file) if
    there is one, checked against the record's hash; else the record's own embedded problem;
    else, for an older record, the problem it names, looked for as a file name in ``folder``
    (the record's own: an older generated problem's witness names its file so) and then as
    any name or path is."""
    recorded = record.get(PROBLEM_HASH_FIELD)
    if given is not None:
        problem = load_problem(given)
        if recorded is not None and recorded != problem.content_hash:
            raise StalmError(
                f"--problem {given}: not the problem {source} was solved on (problem hash "
                f"{problem.content_hash} for the file, {_quoted(recorded)} in the record)"
                + (
                    "; leave --problem out to use the problem the record carries"
                    if PROBLEM_SPEC_FIELD in record
                    else "; give the problem file it was solved on"
                )
            )
        return problem
    embedded = embedded_problem(record, source)
    if embedded is not None:
        return embedded
    named = str(record.get("problem", ""))
    beside = None if folder is None else folder / named
    if (
        beside is not None
        and Path(named).name == named
        and Path(named).suffix in (".yaml", ".yml")
        and beside.is_file()
    ):
        named = str(beside)
    try:
        problem = load_problem(named)
    except StalmError as error:
        raise StalmError(
            f"{error}; {source} does not carry its problem (an older stalm wrote it): pass the "
            "problem file it was solved on with --problem FILE"
        ) from None
    if recorded is not None and recorded != problem.content_hash:
        raise StalmError(
            f"{source}: the record's problem ({_quoted(recorded)}) is not {problem.name} as "
            f"{problem.source} has it ({problem.content_hash}); pass the problem file it was "
            "solved on with --problem FILE"
        )
    return problem


def _quoted(value: object) -> str:
    """A record's hash as an error may quote it: short, printable."""
    return "none" if value is None else excerpt(str(value), _HASH_CHARS)
