"""One version of each problem file per report.

A problem file changed between runs (a suite made again with other arguments, a file edited)
is another problem under the same name: its records pooled with the old one's would make a
cell describe neither (``4/4`` from two files). Records name the version they ran by the
digest of the file's text (``problem_sha``, what the trial's key hashes). The report keeps
the newest version's records and names what it left out, rather than split a problem into
columns a reader could take for different problems.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

from stalm.world.problem import PROBLEM_HASH_FIELD


def problem_version(record: dict[str, Any]) -> str | None:
    """Which version of its problem file a record's trial ran: the digest of the file's text
    (``problem_sha``, what the trial's key hashes), or of the validated problem
    (``problem_hash``) in records that lack it; None if the record names neither."""
    for name in ("problem_sha", PROBLEM_HASH_FIELD):
        if isinstance(record.get(name), str):
            return str(record[name])
    return None


def _finished(record: dict[str, Any]) -> float:
    value = record.get("finished_at", record.get("started_at"))
    if isinstance(value, bool) or not isinstance(value, int | float):
        return -math.inf
    return float(value) if math.isfinite(value) else -math.inf


def newest_problem_versions(
    records: Sequence[dict[str, Any]],
) -> tuple[list[dict[str, Any]], list[str]]:
    """The records of the newest version of each problem, and one note per problem whose
    records ran several versions, naming them and what was left out.

    A problem file changed between runs (a suite made again with other arguments, a file
    edited) is another problem under the same name; pooled, its cell would describe neither
    (``4/4`` from two files). Of each problem's versions the one with the latest finished
    trial counts (``finished_at``; the later record of the files given breaks a tie): the
    older ones' trials are left out, and said so, rather than split into columns a reader
    could take for different problems."""
    versions: dict[str, dict[str | None, list[int]]] = defaultdict(lambda: defaultdict(list))
    for position, record in enumerate(records):
        versions[str(record["problem"])][problem_version(record)].append(position)
    newest = {
        problem: max(found, key=lambda v: max((_finished(records[i]), i) for i in found[v]))
        for problem, found in versions.items()
    }
    notes = []
    for problem, found in versions.items():
        if len(found) < 2:
            continue
        kept = newest[problem]
        older = ", ".join(
            f"{version} ({len(found[version])} records)" for version in found if version != kept
        )
        notes.append(
            f"{problem}: records of {len(found)} versions of the problem file; counted the "
            f"newest, {kept} ({len(found[kept])} records), left out {older}"
        )
    kept_records = [r for r in records if problem_version(r) == newest[str(r["problem"])]]
    return kept_records, notes
