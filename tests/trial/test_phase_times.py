"""The proposer's seconds are the proposer's (issue 42, finding 3).

Fast Downward's runs were charged to a phase named ``llm`` and printed as "LLM 59.8" beside
"LLM calls 0". The phase is now ``proposer``, printed with whose time it was; records written
before (``times.llm``) are read with it as ``proposer`` (tests/trial/test_records.py).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

from stalm.trial.details import RunDetails
from stalm.trial.result import Counters, PhaseTimes, PlanResult

ROOT = Path(__file__).parents[2]
OLD_RECORD = ROOT / "tests" / "planners" / "data" / "p2_result.json"


def test_a_result_writes_the_proposer_phase_not_llm() -> None:
    times = asdict(PhaseTimes(proposer=2.5))
    assert times["proposer"] == 2.5
    assert "llm" not in times


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
