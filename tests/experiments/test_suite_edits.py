"""Properties of suites: whatever edit is made to whatever file of a generated suite (its
index, a problem, a witness), ``experiment scale`` either refuses the suite or runs exactly the
problems that were generated (the same text, the same number of objects); and however records
of several versions of a problem are mixed, the report counts one version per problem (the
newest), never two in one cell."""

from __future__ import annotations

import re
import shutil
import tempfile
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from stalm.errors import StalmError
from stalm.experiments.problem_versions import newest_problem_versions
from stalm.experiments.scale_report import scale_cells
from stalm.experiments.suites import build_plan, trial_specs
from stalm.generate.arrange import Knobs
from stalm.generate.suite import generate_suite

EDITS = settings(
    max_examples=80,
    deadline=None,  # each example copies the suite and reads it: tens of ms, not a bound
    suppress_health_check=[HealthCheck.too_slow],
)
NUMBER = re.compile(rb"-?\d+(?:\.\d+)?")


@pytest.fixture(scope="module")
def suite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One problem of 6 objects, never modified by the tests (each edits a copy)."""
    folder = tmp_path_factory.mktemp("edits") / "suite"
    generate_suite("e", (6,), 1, 5, folder, Knobs(6, 1, 1))
    return folder


def _scale(folder: Path) -> dict[str, tuple[str, object]]:
    """What ``experiment scale`` would run on ``folder``: problem -> (its text, its objects)."""
    specs = trial_specs(build_plan("scale", suite=folder, trials=1, planners=("uct",)))
    return {spec.problem: (spec.problem_yaml, dict(spec.fields)["objects"]) for spec in specs}


def _edited(data: bytes, draw: st.DataObject) -> bytes:
    """``data`` with one edit: bytes replaced, inserted or deleted anywhere, the file cut
    short, or one of its numbers replaced by another."""
    kind = draw.draw(st.sampled_from(["replace", "insert", "delete", "cut", "number"]))
    at = draw.draw(st.integers(0, max(len(data) - 1, 0)))
    if kind == "number":
        numbers = list(NUMBER.finditer(data))
        found = numbers[draw.draw(st.integers(0, len(numbers) - 1))]
        value = draw.draw(
            st.one_of(st.integers(-3, 200), st.floats(-1e3, 1e3, allow_nan=False), st.just(1e308))
        )
        return data[: found.start()] + str(value).encode() + data[found.end() :]
    if kind == "cut":
        return data[:at]
    if kind == "delete":
        return data[:at] + data[at + draw.draw(st.integers(1, 16)) :]
    payload = draw.draw(st.binary(min_size=1, max_size=8))
    return data[:at] + payload + data[at + (len(payload) if kind == "replace" else 0) :]


@EDITS
@given(draw=st.data())
def test_an_edited_suite_is_refused_or_runs_what_was_generated(
    suite: Path, draw: st.DataObject
) -> None:
    generated = _scale(suite)
    names = sorted(path.name for path in suite.iterdir())
    edited_file = draw.draw(st.sampled_from(names), label="file")
    with tempfile.TemporaryDirectory() as temporary:
        copy = Path(temporary) / "suite"
        shutil.copytree(suite, copy)
        before = (copy / edited_file).read_bytes()
        after = _edited(before, draw)
        assume(after != before)
        (copy / edited_file).write_bytes(after)
        try:
            ran = _scale(copy)
        except StalmError:
            event("refused")
            return  # refused, with one message
        event("ran the generated problems")
        assert ran == generated


def _record(problem: int, version: int, arm: int, success: bool, finished: float, key: int):
    return {
        "key": str(key),
        "arm": f"arm{arm}",
        "problem": f"e_{problem:03d}",
        "problem_sha": f"{version:012d}",
        "objects": 6 + 2 * problem,
        "success": success,
        "termination": "goal" if success else "timeout",
        "time_s": 1.0 + finished,
        "time_budget_s": 100.0,
        "finished_at": finished,
    }


RECORDS = st.lists(
    st.tuples(
        st.integers(0, 2),  # problem
        st.integers(0, 2),  # version of its file
        st.integers(0, 1),  # arm
        st.booleans(),
        st.floats(0.0, 50.0, allow_nan=False),  # when it finished
    ),
    min_size=1,
    max_size=40,
)


@settings(max_examples=150, deadline=None)
@given(rows=RECORDS)
def test_the_report_never_pools_two_versions_of_a_problem(rows: list[tuple[Any, ...]]) -> None:
    records = [_record(*row, key=key) for key, row in enumerate(rows)]
    kept, notes = newest_problem_versions(records)
    versions: dict[str, set[str]] = defaultdict(set)
    for record in kept:
        versions[record["problem"]].add(record["problem_sha"])
    assert all(len(found) == 1 for found in versions.values())
    every: dict[str, set[str]] = defaultdict(set)
    for record in records:
        every[record["problem"]].add(record["problem_sha"])
    assert set(versions) == set(every)  # every problem keeps a version
    for problem, (sha,) in versions.items():
        newest = max(
            (r for r in records if r["problem"] == problem),
            key=lambda r: (r["finished_at"], records.index(r)),
        )
        assert sha == newest["problem_sha"]
        assert [r for r in kept if r["problem"] == problem] == [
            r for r in records if r["problem"] == problem and r["problem_sha"] == sha
        ]
    assert len(notes) == sum(len(found) > 1 for found in every.values())
    assert sum(cell.trials for cell in scale_cells(kept).values()) == len(kept)
