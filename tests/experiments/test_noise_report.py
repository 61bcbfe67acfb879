"""The noisy proposer in a report: injected against classified kinds, and the Table 3 curve,
from hand-written records."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from stalm.experiments.noise_report import (
    confusion,
    curve,
    markdown_confusion,
    markdown_curve,
    noise_rate,
    noisy_label,
)
from stalm.experiments.report import write_report


def _plans(*pairs: tuple[str, str]) -> list[dict[str, Any]]:
    return [
        {"step": 0, "round": 0, "index": i, "injected": injected, "kind": kind}
        for i, (injected, kind) in enumerate(pairs)
    ]


def _record(
    key: str,
    row: str,
    problem: str,
    success: bool,
    rate: float | None,
    planner: str = "stalm",
    plans: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    proposer: dict[str, Any] = {"kind": "llm"}
    if rate is not None:
        proposer = {"kind": "noisy", "noise": {"rate": rate, "weights": [1, 1, 1]}}
    details: dict[str, Any] = {}
    if plans is not None:
        details["noise"] = {"rate": rate, "plans": plans}
    return {
        "key": key,
        "arm": noisy_label(row, rate) if rate is not None else row,
        "planner": planner,
        "problem": problem,
        "success": success,
        "termination": "goal" if success else "timeout",
        "time_s": 10.0,
        "time_budget_s": 30.0,
        "settings": {"proposer": proposer},
        "details": details,
    }


HAND_BUILT = _plans(
    # a dropped clearing step: occluded at the first step, or further on (Concretize's 3D)
    ("precondition_violation", "precondition_violation"),
    ("precondition_violation", "lack_of_3d_understanding"),
    # the grill first: no room for the cans after it
    ("lack_of_3d_understanding", "lack_of_3d_understanding"),
    # cut before the last goal objects: every step grounds, the goal is short
    ("partially_achieved_goal", "partially_achieved_goal"),
    ("clean", "reached_goal"),
    ("inapplicable", "partially_achieved_goal"),
    ("clean", "not_tried"),
)


def test_the_confusion_table_counts_each_injected_kind_by_its_classified_kind() -> None:
    records = [
        _record("1", "stalm", "P5", True, 0.5, plans=HAND_BUILT),
        _record("2", "stalm", "P6", True, 0.5, plans=HAND_BUILT[:1]),
        _record("3", "uct", "P5", False, None, planner="uct"),
    ]
    table = confusion(records)
    assert table["precondition_violation"] == {
        "precondition_violation": 2,
        "lack_of_3d_understanding": 1,
    }
    assert table["lack_of_3d_understanding"] == {"lack_of_3d_understanding": 1}
    assert table["partially_achieved_goal"] == {"partially_achieved_goal": 1}
    assert table["clean"] == {"reached_goal": 1, "not_tried": 1}
    assert table["inapplicable"] == {"partially_achieved_goal": 1}
    lines = markdown_confusion(table).splitlines()
    assert lines[0] == (
        "| injected \\ classified | precondition violation | lack of 3d understanding | "
        "partially achieved goal | reached goal | not tried | plans | same kind |"
    )
    assert "| precondition violation | 2 | 1 | 0 | 0 | 0 | 3 | 0.67 |" in lines
    assert "| lack of 3d understanding | 0 | 1 | 0 | 0 | 0 | 1 | 1.00 |" in lines
    assert "| partially achieved goal | 0 | 0 | 1 | 0 | 0 | 1 | 1.00 |" in lines
    assert "| clean | 0 | 0 | 0 | 1 | 1 | 2 | – |" in lines
    assert markdown_confusion({}).startswith("No record holds")


def test_a_record_is_the_noisy_proposers_by_its_settings_and_planner() -> None:
    assert noise_rate(_record("1", "stalm", "P1", True, 0.25)) == 0.25
    assert noise_rate(_record("2", "stalm", "P1", True, None)) is None
    # UCT proposes nothing: whatever its settings say, it is a level line
    assert noise_rate(_record("3", "uct", "P1", True, 0.25, planner="uct")) is None
    assert noise_rate({"arm": "old", "planner": "stalm"}) is None  # a record without settings


def _curve_records() -> list[dict[str, Any]]:
    records = []
    key = 0
    for problem in ("P3", "P5"):
        for rate, wins in ((0.0, (True, True)), (0.5, (True, False)), (1.0, (False, False))):
            for row in ("stalm", "stalm-no-uct"):
                for won in wins if row == "stalm" else (wins[0] and rate == 0.0, False):
                    key += 1
                    records.append(
                        _record(str(key), row, problem, won, rate, planner=row, plans=HAND_BUILT)
                    )
        records.append(_record(f"u{problem}", "uct", problem, problem == "P3", None, "uct"))
    return records


def test_the_curve_is_success_against_the_error_rate_with_uct_beside() -> None:
    data = curve(_curve_records())
    assert data is not None
    assert data.series == ("stalm", "stalm-no-uct") and data.rates == (0.0, 0.5, 1.0)
    assert data.problems == ("P3", "P5")
    assert data.points[("stalm", "P5", 0.5)] == (2, 1)
    assert data.points[("stalm-no-uct", "P3", 0.0)] == (2, 1)
    assert data.levels == {("uct", "P3"): (1, 1), ("uct", "P5"): (1, 0)}
    # 4 of HAND_BUILT's 7 plans carry an injected kind
    assert data.corrupted[("stalm", 0.5)] == (4 * 4, 4 * 7)
    lines = markdown_curve(data).splitlines()
    assert lines[0] == "| Row | Error rate | P3 | P5 | plans corrupted |"
    assert "| stalm | 0.5 | 0.50 (1/2) | 0.50 (1/2) | 0.57 of 28 |" in lines
    assert "| uct | – | 1.00 (1/1) | 0.00 (0/1) | – |" in lines
    # one rate only: no curve to draw
    assert curve([r for r in _curve_records() if "[noisy 0.5]" in r["arm"]]) is None


def test_write_report_adds_the_noise_tables_and_the_curve_plots(tmp_path: Path) -> None:
    text, files = write_report(_curve_records(), tmp_path, name="t3")
    assert "injected against classified kinds" in text
    assert "Success rate against the noisy proposer's error rate" in text
    assert "| stalm [noisy 0.5] | Success rate |" in text  # the rows, labelled with the rate
    names = {path.name for path in files.plots}
    assert {"t3-noise.png", "t3-noise.svg"} <= names
    assert all(path.stat().st_size > 0 for path in files.plots)
    # records of no noisy proposer: no noise section, no curve
    plain, files = write_report([_record("1", "uct", "P1", True, None, "uct")], tmp_path, name="u")
    assert "noisy" not in plain and not any("noise" in p.name for p in files.plots)
