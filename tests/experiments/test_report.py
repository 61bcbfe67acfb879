"""Report tables from hand-written records: rates, mean times of successes, t/o, Figure 5."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

from stalm.experiments.report import (
    build_table,
    csv_table,
    failure_shares,
    markdown_failures,
    markdown_table,
    rows_by_settings,
    write_report,
)


def _record(key: str, arm: str, problem: str, success: bool, time_s: float, **extra: Any) -> dict:
    termination = "goal" if success else extra.pop("termination", "timeout")
    return {
        "key": key,
        "arm": arm,
        "problem": problem,
        "success": success,
        "termination": termination,
        "time_s": time_s,
        "time_budget_s": 30.0,
        **extra,
    }


RECORDS = [
    _record("1", "stalm", "P1", True, 10.0, llm_plan_failures={"precondition_violation": 3}),
    _record("2", "stalm", "P1", True, 20.0, llm_plan_failures={"lack_of_3d_understanding": 1}),
    _record("3", "stalm", "P2", False, 30.0),
    _record("4", "uct", "P1", False, 30.0),
    _record("5", "uct", "P1", False, 3.0, termination="error"),
    _record("6", "uct", "P2", True, 12.0),
    _record("6", "uct", "P2", True, 14.0),  # a re-run of trial 6: the newest record counts
]


def test_cells_hold_rates_mean_success_times_timeouts_and_errors() -> None:
    table = build_table(RECORDS)
    assert table.rows == ("uct", "stalm")  # the paper's order
    assert table.problems == ("P1", "P2")
    stalm_p1 = table.cells[("stalm", "P1")]
    assert (stalm_p1.trials, stalm_p1.successes, stalm_p1.mean_success_time_s) == (2, 2, 15.0)
    uct_p1 = table.cells[("uct", "P1")]
    assert (uct_p1.success_rate, uct_p1.timeouts, uct_p1.errors) == (0.0, 1, 1)
    assert table.cells[("uct", "P2")].mean_success_time_s == 14.0


def test_markdown_is_the_papers_layout_with_t_o_and_the_papers_numbers() -> None:
    text = markdown_table(build_table(RECORDS), paper=True)
    lines = text.splitlines()
    assert lines[0] == "| Method | Metric | P1 | P2 |"
    assert "1 err" in lines[2]  # uct's row
    assert lines[4].startswith("| stalm | Success rate | 1.00 (2/2) [1.00]")
    assert lines[5] == "|  | Time (s) | 15.0 [31.2] | t/o [54.2] |"


def test_csv_has_one_line_per_cell() -> None:
    rows = list(csv.DictReader(io.StringIO(csv_table(build_table(RECORDS)))))
    assert len(rows) == 4
    uct_p1 = next(r for r in rows if r["planner"] == "uct" and r["problem"] == "P1")
    assert uct_p1["mean_success_time_s"] == ""
    assert uct_p1["errors"] == "1"


def test_failure_shares_sum_to_one_per_row_and_problem() -> None:
    shares = failure_shares(RECORDS)
    assert list(shares) == [("stalm", "P1")]
    assert shares[("stalm", "P1")]["precondition_violation"] == 0.75
    assert shares[("stalm", "P1")]["lack_of_3d_understanding"] == 0.25


def test_no_plan_is_its_own_kind_and_old_records_keep_their_unparseable() -> None:
    """The symbolic proposer's "no plan found" is ``no_plan`` in new records; an older record
    counted it as ``unparseable`` and still reports as it was written."""
    records = [
        _record("o", "stalm-symbolic", "P3", False, 30.0, llm_plan_failures={"unparseable": 1}),
        _record("n", "stalm-symbolic", "P3", False, 30.0, llm_plan_failures={"no_plan": 1}),
        _record("l", "stalm-symbolic", "P3", False, 30.0, llm_plan_failures={"no_plan": 2}),
    ]
    share = failure_shares(records)[("stalm-symbolic", "P3")]
    assert share["no_plan"] == 0.75 and share["unparseable"] == 0.25
    header = markdown_failures(failure_shares(records)).splitlines()[0]
    assert header == "| Method | Problem | unparseable | no plan |"
    # without a no_plan anywhere, the table has no such column (old reports are unchanged)
    assert "no plan" not in markdown_failures(failure_shares(records[:1]))


def test_rows_follow_the_papers_order_whatever_finished_first() -> None:
    table = build_table([RECORDS[3], RECORDS[0], _record("9", "mine", "P1", True, 1.0)])
    assert table.rows == ("uct", "stalm", "mine")


def test_write_report_saves_markdown_csv_and_plots(tmp_path: Path) -> None:
    text, files = write_report(RECORDS, tmp_path, name="t", formats=("png", "svg"))
    assert files.markdown.read_text() == text
    assert "Figure 5" in text
    assert {p.name for p in files.plots} == {
        "t-success.png",
        "t-success.svg",
        "t-failures.png",
        "t-failures.svg",
    }
    assert (tmp_path / "t-success.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in (tmp_path / "t-failures.svg").read_bytes()[:400]


def test_the_papers_numbers_are_rounded_as_the_paper_writes_them() -> None:
    """356.65 and 165.85 lie between floats; the paper's decimals round half up."""
    records = [
        _record("7", "uct-hcount", "P5", False, 30.0),
        _record("10", "uct-hcount", "P6", False, 30.0),
        _record("8", "stalm", "P6", False, 30.0),
        _record("9", "stalm", "P4", False, 30.0),
    ]
    text = markdown_table(build_table(records), paper=True)
    assert "t/o [356.7]" in text and "t/o [t/o]" in text  # Hcount's P5; its P6 timed out
    assert "t/o [165.9]" in text and "[0.96]" in text  # STaLM's P6 time and P4 success


def test_a_scale_run_is_reported_by_object_count_with_the_log_log_slope(tmp_path: Path) -> None:
    from stalm.experiments.scale_report import scale_cells, slope

    records = [_record(str(n), "row", f"g{n}", True, 0.5 * n, objects=n) for n in (8, 16, 32)] + [
        _record("f", "row", "g64", False, 600.0, objects=64)
    ]
    cells = scale_cells(records)
    assert cells[("row", 64)].successes == 0 and cells[("row", 8)].mean_success_time_s == 4.0
    assert abs(slope([(8, 4.0), (16, 8.0), (32, 16.0)]) - 1.0) < 1e-9  # linear in objects
    assert slope([(8, 4.0)]) is None
    text, files = write_report(records, tmp_path, name="s")
    assert "| row | 1/1, 4.0 s | 1/1, 8.0 s | 1/1, 16.0 s | 0/1, t/o | 1.00 |" in text
    assert any(path.name == "s-scale.png" for path in files.plots)


def test_one_arm_run_with_two_settings_is_two_rows_and_a_retried_trial_counts_once(
    tmp_path: Path,
) -> None:
    """Two results files of ``stalm-symbolic``, one run with ``--set``: averaged into one row
    they would describe neither run. A trial recorded twice (a rerun) counts once, the newest."""
    relevant = {"settings": {"predicates.relevant_only": True}}
    records = [
        _record("a8", "stalm-symbolic", "g8", True, 4.0, objects=8, config={}),
        _record("a64", "stalm-symbolic", "g64", False, 600.0, objects=64, config={}),
        _record("a64", "stalm-symbolic", "g64", True, 32.0, objects=64, config={}),  # rerun
        _record("r8", "stalm-symbolic", "g8", True, 2.0, objects=8, config=relevant),
        _record("r64", "stalm-symbolic", "g64", True, 16.0, objects=64, config=relevant),
    ]
    text, _ = write_report(records, tmp_path, name="split", formats=())
    assert "| stalm-symbolic | 1/1, 4.0 s | 1/1, 32.0 s | 1.00 |" in text
    relevant_row = "| stalm-symbolic [predicates.relevant_only=true] | 1/1, 2.0 s | 1/1, 16.0 s |"
    assert relevant_row + " 1.00 |" in text
    # one set of settings under a label: the label stays as it is
    alone, _ = write_report(records[3:], tmp_path, name="alone", formats=())
    assert "| stalm-symbolic | 1/1, 2.0 s | 1/1, 16.0 s | 1.00 |" in alone


def test_a_flat_choice_that_differs_splits_the_rows_too(tmp_path: Path) -> None:
    """``--set reuse_tree=false`` changes a flat choice of the record's ``config`` (not its
    ``settings``): both rows say which value they ran with."""
    records = [
        _record("p", "stalm-symbolic", "P3", True, 4.0, config={"reuse_tree": True}),
        _record("q", "stalm-symbolic", "P3", False, 30.0, config={"reuse_tree": False}),
    ]
    table = build_table(rows_by_settings(records))
    assert table.rows == ("stalm-symbolic [reuse_tree=true]", "stalm-symbolic [reuse_tree=false]")
    assert table.cells[("stalm-symbolic [reuse_tree=false]", "P3")].successes == 0
    # the same choices everywhere: one row, as before
    same = [{**record, "config": {"reuse_tree": True}} for record in records]
    assert build_table(rows_by_settings(same)).rows == ("stalm-symbolic",)
