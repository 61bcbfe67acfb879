"""The proposer's seconds are the proposer's (issue 42, finding 3).

Fast Downward's runs were charged to a phase named ``llm`` and printed as "LLM 59.8" beside
"LLM calls 0". The phase is now ``proposer``, printed with whose time it was; records written
before (``times.llm``, in ``docs/results`` and ``tests/planners/data``) still load, their
``llm`` read as ``proposer``.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import pytest

from stalm.trial.details import RunDetails
from stalm.trial.result import Counters, PhaseTimes, PlanResult, phase_times_json

ROOT = Path(__file__).parents[2]
OLD_RECORD = ROOT / "tests" / "planners" / "data" / "p2_result.json"


def test_a_result_writes_the_proposer_phase_not_llm() -> None:
    times = asdict(PhaseTimes(proposer=2.5))
    assert times["proposer"] == 2.5
    assert "llm" not in times


def test_an_old_record_reads_its_llm_seconds_as_the_proposer_s() -> None:
    data = json.loads(OLD_RECORD.read_text(encoding="utf-8"))
    assert "llm" in data["times"]  # written before the rename
    times = PhaseTimes.from_json(data["times"])
    assert times.proposer == data["times"]["llm"]
    assert times.predicates == data["times"]["predicates"]
    assert times.total == data["times"]["total"]


def test_the_new_key_wins_and_junk_is_left_out() -> None:
    both = {"llm": 1.0, "proposer": 2.0, "total": 5.0, "tree_search": "x", "extra": 3.0}
    assert phase_times_json(both)["proposer"] == 2.0
    assert PhaseTimes.from_json(both) == PhaseTimes(proposer=2.0, total=5.0)
    assert PhaseTimes.from_json(None) == PhaseTimes()
    assert PhaseTimes.from_json({"total": float("nan")}) == PhaseTimes()


def test_every_saved_record_in_docs_results_still_loads() -> None:
    """Each record of docs/results with phase times loads, old key or new."""
    seen = 0
    for path in sorted((ROOT / "docs" / "results").rglob("*.jsonl"))[:40]:
        for line in path.read_text(encoding="utf-8").splitlines()[:20]:
            record = json.loads(line)
            if isinstance(record, dict) and isinstance(record.get("times"), dict):
                times = PhaseTimes.from_json(record["times"])
                assert times.total == pytest.approx(float(record["times"]["total"]))
                if "llm" in record["times"]:
                    assert times.proposer == pytest.approx(float(record["times"]["llm"]))
                seen += 1
    assert seen > 0


@dataclass(frozen=True)
class ProposerDetailsDouble:
    """A method's record that names only its proposer."""

    proposer: str

    def to_json(self) -> dict[str, object]:
        return {"proposer": self.proposer}


def _result(proposer: str, llm_calls: int = 0) -> PlanResult:
    return PlanResult(
        problem="P2",
        planner="stalm",
        seed=0,
        success=False,
        plan=(),
        states=(),
        times=PhaseTimes(proposer=59.8, total=300.0),
        counters=Counters(llm_calls=llm_calls),
        termination="horizon",
        details=RunDetails(ProposerDetailsDouble(proposer)),
    )


def test_the_summary_says_fast_downward_s_seconds_are_the_proposer_s(capsys) -> None:
    from stalm.cli.solve_output import print_result

    print_result(_result("symbolic:fast-downward"))
    printed = " ".join(capsys.readouterr().out.split())
    assert "proposer (Fast Downward) 59.8" in printed
    assert "LLM 59.8" not in printed


def test_the_summary_says_a_model_s_seconds_are_the_model_s(capsys) -> None:
    from stalm.cli.solve_output import print_result

    print_result(_result("llm:openai:gpt-4", llm_calls=3))
    printed = " ".join(capsys.readouterr().out.split())
    assert "proposer (model) 59.8" in printed
