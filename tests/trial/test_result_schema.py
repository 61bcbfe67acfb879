"""The published schema of result records holds for every record committed under
docs/results, for the solve records the tests keep, and for a fresh ``stalm solve --json``;
and it refuses a record that breaks it, so the check can fail."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator

from stalm.trial.result_schema import result_schema
from tests.cli_runner import run_cli

ROOT = Path(__file__).resolve().parents[2]
NOT_RESULT_LOGS = {
    "issue13/p5-tail.jsonl": "a per-step benchmark of one P5 trial's tail, not trials",
    "issue13/fast-downward-scaling.jsonl": "Fast Downward's grounding sizes, not trials",
}
"""JSON-lines files under docs/results that hold measurements of another kind."""
SOLVE_RECORDS = (
    "tests/planners/data/p2_result.json",
    "tests/trial/data/p5_result.json",
    "tests/viz/data/p2_steps_result.json",
)


@pytest.fixture(scope="module")
def validator() -> Draft202012Validator:
    schema = result_schema()
    Draft202012Validator.check_schema(schema)
    return Draft202012Validator(schema)


def _committed_records() -> list[tuple[str, dict]]:
    records = []
    for path in sorted((ROOT / "docs" / "results").rglob("*.jsonl")):
        name = path.relative_to(ROOT / "docs" / "results").as_posix()
        if name in NOT_RESULT_LOGS:
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if line.strip():
                records.append((f"{name}:{number}", json.loads(line)))
    return records


def _problems(validator: Draft202012Validator, record: dict) -> list[str]:
    return [
        f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(record)
    ]


@pytest.mark.slow  # 3,000 records, 99 MB: about a minute
def test_every_committed_record_follows_the_schema(validator) -> None:
    records = _committed_records()
    assert len(records) > 3000  # every results log there, not an empty glob
    broken = {where: _problems(validator, record)[:1] for where, record in records}
    assert {where: why for where, why in broken.items() if why} == {}
    kinds = {("experiment" in r, "error" in r) for _, r in records}
    assert kinds == {(True, False), (True, True)}  # trials, and trials that raised


@pytest.mark.parametrize("name", SOLVE_RECORDS)
def test_the_solve_records_the_tests_keep_follow_the_schema(validator, name: str) -> None:
    assert _problems(validator, json.loads((ROOT / name).read_text())) == []


def test_a_fresh_solve_record_follows_the_schema(validator, monkeypatch, tmp_path) -> None:
    out = tmp_path / "p2.json"
    args = ["solve", "P2", "--planner", "uct", "--sims", "3", "--set", "budget.horizon=2"]
    assert run_cli(monkeypatch, *args, "--json", str(out)) in (0, 1)
    record = json.loads(out.read_text())
    assert record["details"]["step_log"], "a tree planner's record keeps its step log"
    assert _problems(validator, record) == []


def test_a_record_that_breaks_the_schema_is_refused_naming_the_field(validator) -> None:
    log = ROOT / "docs" / "results" / "issue41" / "stalm-symbolic-feedback.jsonl"
    record = json.loads(log.read_text().splitlines()[0])
    assert record["details"]["step_log"] and _problems(validator, record) == []
    pick = next(i for i, a in enumerate(record["plan"]) if a["action"][0] == "pick")
    cases = {
        "details/step_log/0/decision": ("details", "step_log", 0, "decision", "coin_toss"),
        "seed": ("seed", -1),
        f"plan/{pick}/grasp/orientation": ("plan", pick, "grasp", "orientation", [0.0] * 5),
        f"plan/{pick}": ("plan", pick, "gripper_width", 0.05),
        "termination": ("termination", "gave_up"),
    }
    for field, (*path, key, value) in cases.items():
        broken = copy.deepcopy(record)
        target = broken
        for step in path:
            target = target[step]
        target[key] = value
        problems = _problems(validator, broken)
        assert problems and any(p.startswith(f"{field}: ") for p in problems), (field, problems)
