"""Tables and plots from trial records, laid out like the paper's.

A cell is one (row label, problem): the success rate over its trials and the mean planning
time of the successes, or ``t/o`` when none succeeded (the paper's convention). Trials that
ended in a planner exception are counted apart (``errors``), never as time-outs. Figure 5 is
the share of the proposer's failed task plans by kind, per problem, over every record that
has them (STaLM's and STaLM w/o UCT's). Records of the noisy proposer add its confusion table
and the success-against-error-rate curve (:mod:`stalm.experiments.noise_report`).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path
from typing import Any

from stalm.experiments.markdown_cells import cell as markdown_cell
from stalm.experiments.noise_report import (
    confusion,
    curve,
    markdown_confusion,
    markdown_curve,
    noise_rate,
    plot_curve,
)
from stalm.experiments.paper_tables import TABLE2
from stalm.experiments.problem_versions import newest_problem_versions
from stalm.experiments.scale_report import has_sizes, markdown_scale, plot_scale, scale_cells
from stalm.search.concretize import FAILURE_KINDS
from stalm.settings.io import dotted


@dataclass(frozen=True)
class Cell:
    """The outcome of one row on one problem."""

    trials: int
    successes: int
    mean_success_time_s: float | None
    timeouts: int
    errors: int
    budget_s: float

    @property
    def success_rate(self) -> float:
        return self.successes / self.trials if self.trials else 0.0


@dataclass(frozen=True)
class Table:
    """Rows (arm labels) by columns (problems), in first-seen order."""

    rows: tuple[str, ...]
    problems: tuple[str, ...]
    cells: dict[tuple[str, str], Cell]
    success_times: dict[tuple[str, str], tuple[float, ...]]


def latest_records(records: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One record per trial key, the newest (a retried trial's final outcome)."""
    latest: dict[str, dict[str, Any]] = {}
    for record in records:
        latest[str(record["key"])] = record
    return list(latest.values())


def config_choices(record: dict[str, Any]) -> dict[str, str]:
    """The choices a record's trial ran with (its ``config``, what its key hashes), flat:
    dotted names to JSON values; the ``--set`` overrides beyond the flat choices
    (``config["settings"]``) under their own dotted names."""
    config = dict(record.get("config") or {})
    overrides = config.pop("settings", None) or {}
    return {name: json.dumps(value) for name, value in (dotted(config) | overrides).items()}


def rows_by_settings(records: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """The newest record of each trial, each under the row it belongs to.

    A row is an arm label run with one configuration. Results files given together may hold
    the same arm run with different choices (``stalm-symbolic``, and ``stalm-symbolic`` run
    with ``--set predicates.relevant_only=true``); averaged into one row they would describe
    neither. So where one label ran with several configurations, each record's label gains,
    in brackets, the choices that differ among them and that its own configuration names (a
    run with the defaults, whose configuration does not name an override, keeps the plain
    label). A label that ran with one configuration keeps its name: the arms that say their
    settings in their labels (Table 3's noisy rows) read as they always did."""
    latest = latest_records(records)
    choices = [config_choices(record) for record in latest]
    names: dict[str, set[str]] = defaultdict(set)
    for record, chosen in zip(latest, choices, strict=True):
        names[str(record["arm"])] |= set(chosen)
    values: dict[tuple[str, str], set[str]] = defaultdict(set)  # (arm, name) -> values
    for record, chosen in zip(latest, choices, strict=True):
        for name in names[str(record["arm"])]:
            values[(str(record["arm"]), name)].add(chosen.get(name, "(default)"))
    rows = []
    for record, chosen in zip(latest, choices, strict=True):
        arm = str(record["arm"])
        differing = [name for name in sorted(chosen) if len(values[(arm, name)]) > 1]
        if differing:
            told = ", ".join(f"{name}={chosen[name]}" for name in differing)
            record = {**record, "arm": f"{record['arm']} [{told}]"}
        rows.append(record)
    return rows


def build_table(records: Iterable[dict[str, Any]]) -> Table:
    groups: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    rows: list[str] = []
    problems: list[str] = []
    for record in latest_records(records):
        row, problem = str(record["arm"]), str(record["problem"])
        if row not in rows:
            rows.append(row)
        if problem not in problems:
            problems.append(problem)
        groups[(row, problem)].append(record)
    cells = {}
    times = {}
    for key, group in groups.items():
        success = [float(r["time_s"]) for r in group if r.get("success")]
        cells[key] = Cell(
            trials=len(group),
            successes=len(success),
            mean_success_time_s=sum(success) / len(success) if success else None,
            timeouts=sum(r.get("termination") == "timeout" for r in group),
            errors=sum(r.get("termination") == "error" for r in group),
            budget_s=max(float(r.get("time_budget_s", 0.0)) for r in group),
        )
        times[key] = tuple(sorted(success))
    return Table(_paper_order(rows), tuple(sorted(problems)), cells, times)


def _paper_order(rows: list[str]) -> tuple[str, ...]:
    """Rows named like Table 2's in the paper's order, then the others as first seen (a run
    with two workers finishes trials out of order, so first-seen alone would shuffle rows)."""
    known = [name for name in TABLE2 if name in rows]
    return tuple(known + [row for row in rows if row not in known])


def _time_text(seconds: float | None) -> str:
    return "t/o" if seconds is None else f"{seconds:.1f}"


def _paper_text(value: float, places: int) -> str:
    """A number the paper prints in decimal, rounded half up as written (356.65 -> 356.7;
    the float nearest 356.65 lies below it, so plain formatting would give 356.6)."""
    exact = Decimal(repr(value)).quantize(Decimal(1).scaleb(-places), rounding=ROUND_HALF_UP)
    return str(exact)


def markdown_table(table: Table, *, paper: bool = False) -> str:
    """The paper's layout: two lines per row (success rate, time), a column per problem.

    With ``paper``, rows whose label is a Table 2 planner get the paper's numbers beside
    ours as ``ours (paper)``.
    """
    head = "| Method | Metric | " + " | ".join(map(markdown_cell, table.problems)) + " |"
    lines = [head, "| --- | --- | " + " | ".join("---" for _ in table.problems) + " |"]
    for row in table.rows:
        rates, times = [], []
        for problem in table.problems:
            cell = table.cells.get((row, problem))
            published = TABLE2.get(row, {}).get(problem) if paper else None
            if cell is None:
                rates.append("–")
                times.append("–")
                continue
            rate = f"{cell.success_rate:.2f} ({cell.successes}/{cell.trials})"
            time = _time_text(cell.mean_success_time_s)
            if cell.errors:
                rate += f", {cell.errors} err"
            if published is not None:
                rate += f" [{_paper_text(published[0], 2)}]"
                paper_time = published[1]
                time += f" [{'t/o' if paper_time is None else _paper_text(paper_time, 1)}]"
            rates.append(rate)
            times.append(time)
        lines.append(f"| {markdown_cell(row)} | Success rate | " + " | ".join(rates) + " |")
        lines.append("|  | Time (s) | " + " | ".join(times) + " |")
    return "\n".join(lines) + "\n"


def csv_table(table: Table) -> str:
    """One line per cell, for spreadsheets and scripts."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        [
            "planner",
            "problem",
            "trials",
            "successes",
            "success_rate",
            "mean_success_time_s",
            "timeouts",
            "errors",
            "budget_s",
        ]
    )
    for row in table.rows:
        for problem in table.problems:
            cell = table.cells.get((row, problem))
            if cell is None:
                continue
            mean = cell.mean_success_time_s
            writer.writerow(
                [
                    row,
                    problem,
                    cell.trials,
                    cell.successes,
                    f"{cell.success_rate:.4f}",
                    "" if mean is None else f"{mean:.3f}",
                    cell.timeouts,
                    cell.errors,
                    f"{cell.budget_s:g}",
                ]
            )
    return buffer.getvalue()


def failure_shares(records: Iterable[dict[str, Any]]) -> dict[tuple[str, str], dict[str, float]]:
    """Figure 5: per (row, problem), each failure kind's share of the failed task plans.

    Kept per row, because a model's mistakes and a classical planner's are different things.
    """
    counts: dict[tuple[str, str], dict[str, int]] = defaultdict(
        lambda: dict.fromkeys(FAILURE_KINDS, 0)
    )
    for record in latest_records(records):
        key = (str(record["arm"]), str(record["problem"]))
        for kind, count in (record.get("llm_plan_failures") or {}).items():
            counts[key][kind] = counts[key].get(kind, 0) + int(count)
    shares = {}
    for key in sorted(counts):
        total = sum(counts[key].values())
        if total:
            shares[key] = {kind: n / total for kind, n in counts[key].items()}
    return shares


def markdown_failures(shares: dict[tuple[str, str], dict[str, float]]) -> str:
    if not shares:
        return "No record holds failed task plans (Figure 5 needs STaLM's records).\n"
    kinds = [k for k in FAILURE_KINDS if any(s.get(k) for s in shares.values())]
    lines = ["| Method | Problem | " + " | ".join(k.replace("_", " ") for k in kinds) + " |"]
    lines.append("| --- | --- | " + " | ".join("---" for _ in kinds) + " |")
    for (row, problem), share in shares.items():
        values = " | ".join(f"{share.get(k, 0):.2f}" for k in kinds)
        lines.append(f"| {markdown_cell(row)} | {markdown_cell(problem)} | {values} |")
    return "\n".join(lines) + "\n"


def plot_success_over_time(table: Table, path: Path) -> Path:
    """Per problem, the share of trials solved by time t for every row (PNG or SVG by the
    suffix of ``path``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = min(3, len(table.problems)) or 1
    lines = math.ceil(len(table.problems) / columns) or 1
    figure, axes = plt.subplots(lines, columns, figsize=(4.2 * columns, 3.2 * lines), squeeze=False)
    for index, problem in enumerate(table.problems):
        axis = axes[index // columns][index % columns]
        budget = max(
            (table.cells[(r, problem)].budget_s for r in table.rows if (r, problem) in table.cells),
            default=1.0,
        )
        # a running simulation is never cut, so a success may land just past the budget
        latest = [t for r in table.rows for t in table.success_times.get((r, problem), ())]
        budget = max([budget, *latest])
        for row in table.rows:
            cell = table.cells.get((row, problem))
            if cell is None:
                continue
            solved = table.success_times[(row, problem)]
            xs = [0.0, *solved, budget]
            ys = [0.0, *[(i + 1) / cell.trials for i in range(len(solved))], cell.success_rate]
            axis.step(xs, ys, where="post", label=row)
        axis.set_title(problem)
        axis.set_xlim(0, budget)
        axis.set_ylim(0, 1.02)
        axis.set_xlabel("planning time (s)")
        axis.set_ylabel("success rate")
    for index in range(len(table.problems), lines * columns):
        axes[index // columns][index % columns].axis("off")
    handles, labels = axes[0][0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="lower center", ncol=min(4, len(labels) or 1))
    figure.tight_layout(rect=(0, 0.08, 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    plt.close(figure)
    return path


def plot_failures(shares: dict[tuple[str, str], dict[str, float]], path: Path) -> Path:
    """Figure 5 as stacked bars: the failure kinds' shares per row and problem."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(shares)
    labels = [f"{row}\n{problem}" for row, problem in keys]
    figure, axis = plt.subplots(figsize=(max(6.0, 0.9 * len(keys)), 3.8))
    bottom = [0.0] * len(keys)
    for kind in FAILURE_KINDS:
        values = [shares[k].get(kind, 0.0) for k in keys]
        if not any(values):
            continue
        axis.bar(labels, values, bottom=bottom, label=kind.replace("_", " "))
        bottom = [b + v for b, v in zip(bottom, values, strict=True)]
    axis.set_ylabel("share of failed task plans")
    axis.tick_params(axis="x", labelsize="x-small")
    axis.set_ylim(0, 1)
    axis.legend(fontsize="small")
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    plt.close(figure)
    return path


@dataclass(frozen=True)
class ReportFiles:
    markdown: Path
    csv: Path
    plots: tuple[Path, ...]
    left_out: tuple[str, ...] = ()
    """Records not counted, one line per problem (:func:`newest_problem_versions`)."""


def write_report(
    records: Sequence[dict[str, Any]],
    out_dir: Path,
    *,
    name: str = "report",
    paper: bool = False,
    formats: Sequence[str] = ("png", "svg"),
) -> tuple[str, ReportFiles]:
    """Write ``name``.md, ``name``.csv and the plots into ``out_dir``; return the Markdown.

    Every table and plot counts the newest record of each trial (a retried trial once), of
    the newest version of each problem file (:func:`newest_problem_versions`; the others are
    named under "Records left out" and in ``left_out``), in rows split by settings where one
    label ran with several (:func:`rows_by_settings`)."""
    current, left_out = newest_problem_versions(records)
    records = rows_by_settings(current)
    table = build_table(records)
    shares = failure_shares(records)
    sized = has_sizes(records)
    if sized:  # a scale run: by object count, not one column per generated problem
        cells = scale_cells(records)
        text = "## Success rate and mean time of successes by number of objects\n\n"
        text += markdown_scale(cells)
    else:
        text = "## Success rate and mean planning time of successes\n\n"
        text += markdown_table(table, paper=paper)
    if paper and not sized:
        text += "\nIn brackets: the paper's Table 2 (50 trials, GPT-4-turbo, full budgets).\n"
    text += "\n## Failed task plans by kind (Figure 5)\n\n" + markdown_failures(shares)
    noise_curve = None
    if any(noise_rate(record) is not None for record in records):
        text += "\n## The noisy proposer (no language model): injected against classified kinds\n\n"
        text += markdown_confusion(confusion(records))
        noise_curve = curve(records)
        if noise_curve is not None:
            text += "\n## Success rate against the noisy proposer's error rate\n\n"
            text += markdown_curve(noise_curve)
    if left_out:
        text += "\n## Records left out (an older version of their problem file)\n\n"
        text += "".join(f"- {markdown_cell(note)}\n" for note in left_out)
    out_dir.mkdir(parents=True, exist_ok=True)
    markdown_path = out_dir / f"{name}.md"
    markdown_path.write_text(text, encoding="utf-8")
    csv_path = out_dir / f"{name}.csv"
    csv_path.write_text(csv_table(table), encoding="utf-8")
    plots = []
    for suffix in formats:
        if sized:
            plots.append(plot_scale(cells, out_dir / f"{name}-scale.{suffix}"))
        plots.append(plot_success_over_time(table, out_dir / f"{name}-success.{suffix}"))
        if shares:
            plots.append(plot_failures(shares, out_dir / f"{name}-failures.{suffix}"))
        if noise_curve is not None:
            plots.append(plot_curve(noise_curve, out_dir / f"{name}-noise.{suffix}"))
    return text, ReportFiles(markdown_path, csv_path, tuple(plots), tuple(left_out))
