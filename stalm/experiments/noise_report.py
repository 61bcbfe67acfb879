"""The noisy proposer's part of a report: what it injected against what Figure 5's classifier
saw, and Table 3 as a curve (success rate against the error rate).

The noisy proposer (:mod:`stalm.proposers.noisy`) is a degraded proposer, not a language
model: its rows are labelled ``ROW [noisy RATE]`` (:func:`noisy_label`) and never by a model's
name. A record is the noisy proposer's when its settings say ``proposer.kind: noisy`` and its
planner takes task plans from the proposer (STaLM, STaLM w/o UCT); its error rate is its
``proposer.noise.rate``, read from the settings so that a trial that ended in an error still
counts in its cell. The curve's series is the label without the rate; every other row of the
same records (UCT, which proposes nothing) is drawn beside it as a level line.
"""

from __future__ import annotations

import math
import re
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stalm.experiments.markdown_cells import cell as markdown_cell
from stalm.planners.registry import PROPOSING
from stalm.search.concretize import FAILURE_KINDS
from stalm.settings.tree import NOISE_KINDS

INJECTED_ROWS = ("clean", "inapplicable", *NOISE_KINDS)
"""The confusion table's rows: not drawn for corruption, drawn but no kind applied, a kind."""
CLASSIFIED_COLUMNS = (*FAILURE_KINDS, "reached_goal", "not_tried")
"""Its columns: Figure 5's kinds, a plan that reached the goal, a plan Concretize never tried
(it stops at the first goal plan)."""
_RATE = re.compile(r" \[noisy [^\]]*\]")


def noisy_label(row: str, rate: float) -> str:
    """The label of ``row`` run on the noisy proposer at error rate ``rate``."""
    return f"{row} [noisy {rate:g}]"


def noise_rate(record: dict[str, Any]) -> float | None:
    """The error rate of a record of the noisy proposer (None for any other record)."""
    settings = record.get("settings")
    proposer = settings.get("proposer") if isinstance(settings, dict) else None
    if not isinstance(proposer, dict) or proposer.get("kind") != "noisy":
        return None
    if record.get("planner") not in PROPOSING:
        return None
    noise = proposer.get("noise")
    rate = noise.get("rate") if isinstance(noise, dict) else None
    return float(rate) if isinstance(rate, int | float) else None


def confusion(records: Iterable[dict[str, Any]]) -> dict[str, dict[str, int]]:
    """Plans by injected label (rows) and classified kind (columns), over ``details.noise``."""
    counts: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    for record in records:
        details = record.get("details")
        noise = details.get("noise") if isinstance(details, dict) else None
        plans = noise.get("plans") if isinstance(noise, dict) else None
        for plan in plans or ():
            counts[str(plan.get("injected"))][str(plan.get("kind"))] += 1
    return {row: dict(columns) for row, columns in counts.items()}


def markdown_confusion(table: dict[str, dict[str, int]]) -> str:
    """The confusion table; the last column is the share of a kind's plans the classifier
    gave that kind (they need not agree: a dropped clearing step leaves a *later* step
    occluded, and the classifier calls only an occluded *first* step a precondition
    violation)."""
    if not table:
        return "No record holds the noisy proposer's plans.\n"
    rows = [r for r in INJECTED_ROWS if r in table or r in NOISE_KINDS]
    rows += sorted(r for r in table if r not in rows)
    seen = {c for columns in table.values() for c in columns}
    columns = [c for c in CLASSIFIED_COLUMNS if c in seen or c in NOISE_KINDS]
    columns += sorted(c for c in seen if c not in columns)
    head = " | ".join(markdown_cell(c.replace("_", " ")) for c in columns)
    lines = [f"| injected \\ classified | {head} | plans | same kind |"]
    lines.append("| --- | " + " | ".join("---" for _ in columns) + " | --- | --- |")
    for row in rows:
        counts = table.get(row, {})
        total = sum(counts.values())
        same = f"{counts.get(row, 0) / total:.2f}" if row in NOISE_KINDS and total else "–"
        cells = " | ".join(str(counts.get(c, 0)) for c in columns)
        lines.append(f"| {markdown_cell(row.replace('_', ' '))} | {cells} | {total} | {same} |")
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class Curve:
    """Success per (series, problem, rate) of the noisy rows, and per (row, problem) of the
    others (drawn level beside them); the share of plans corrupted per (series, rate)."""

    points: dict[tuple[str, str, float], tuple[int, int]]
    levels: dict[tuple[str, str], tuple[int, int]]
    corrupted: dict[tuple[str, float], tuple[int, int]]

    @property
    def series(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(s for s, _, _ in self.points))

    @property
    def problems(self) -> tuple[str, ...]:
        found = {p for _, p, _ in self.points} | {p for _, p in self.levels}
        return tuple(sorted(found))

    @property
    def rates(self) -> tuple[float, ...]:
        return tuple(sorted({r for _, _, r in self.points}))


def curve(records: Sequence[dict[str, Any]]) -> Curve | None:
    """The curve of ``records`` (one per trial), or None when no series has two rates."""
    points: dict[tuple[str, str, float], list[int]] = defaultdict(lambda: [0, 0])
    levels: dict[tuple[str, str], list[int]] = defaultdict(lambda: [0, 0])
    corrupted: dict[tuple[str, float], list[int]] = defaultdict(lambda: [0, 0])
    for record in records:
        label, problem = str(record["arm"]), str(record["problem"])
        success = int(bool(record.get("success")))
        rate = noise_rate(record)
        if rate is None:
            cell = levels[(label, problem)]
        else:
            series = _RATE.sub("", label)
            cell = points[(series, problem, rate)]
            plans = confusion([record])
            share = corrupted[(series, rate)]
            share[0] += sum(sum(plans.get(k, {}).values()) for k in NOISE_KINDS)
            share[1] += sum(sum(columns.values()) for columns in plans.values())
        cell[0] += 1
        cell[1] += success
    rates_per_series: dict[str, set[float]] = defaultdict(set)
    for series, _, rate in points:
        rates_per_series[series].add(rate)
    if not any(len(rates) > 1 for rates in rates_per_series.values()):
        return None

    def frozen(cells: dict[Any, list[int]]) -> dict[Any, tuple[int, int]]:
        return {key: (value[0], value[1]) for key, value in cells.items()}

    return Curve(frozen(points), frozen(levels), frozen(corrupted))


def markdown_curve(data: Curve) -> str:
    """Success rate (successes/trials) per series and rate, a column per problem, then the
    level rows; and the share of plans the noisy proposer corrupted at each rate."""
    problems = data.problems
    lines = [
        "| Row | Error rate | " + " | ".join(map(markdown_cell, problems)) + " | plans corrupted |"
    ]
    lines.append("| --- | --- | " + " | ".join("---" for _ in problems) + " | --- |")
    for series in data.series:
        for rate in data.rates:
            cells = [data.points.get((series, p, rate)) for p in problems]
            if not any(cells):
                continue
            texts = [_rate_text(cell) for cell in cells]
            done, plans = data.corrupted.get((series, rate), (0, 0))
            share = f"{done / plans:.2f} of {plans}" if plans else "–"
            lines.append(
                f"| {markdown_cell(series)} | {rate:g} | " + " | ".join(texts) + f" | {share} |"
            )
    for row in dict.fromkeys(r for r, _ in data.levels):
        texts = [_rate_text(data.levels.get((row, p))) for p in problems]
        lines.append(f"| {markdown_cell(row)} | – | " + " | ".join(texts) + " | – |")
    return "\n".join(lines) + "\n"


def _rate_text(cell: tuple[int, int] | None) -> str:
    if cell is None:
        return "–"
    trials, successes = cell
    return f"{successes / trials:.2f} ({successes}/{trials})"


def plot_curve(data: Curve, path: Path) -> Path:
    """Per problem, success rate against the noisy proposer's error rate for every series,
    the other rows as dashed level lines (PNG or SVG by the suffix of ``path``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    problems = data.problems
    columns = min(3, len(problems)) or 1
    lines = math.ceil(len(problems) / columns) or 1
    figure, axes = plt.subplots(lines, columns, figsize=(4.2 * columns, 3.2 * lines), squeeze=False)
    for index, problem in enumerate(problems):
        axis = axes[index // columns][index % columns]
        for series in data.series:
            xs = [r for r in data.rates if (series, problem, r) in data.points]
            ys = [_share(data.points[(series, problem, r)]) for r in xs]
            axis.plot(xs, ys, marker="o", label=series)
        for row in dict.fromkeys(r for r, _ in data.levels):
            cell = data.levels.get((row, problem))
            if cell is not None:
                axis.axhline(_share(cell), linestyle="--", color="grey", label=row)
        axis.set_title(problem)
        axis.set_xlim(-0.03, 1.03)
        axis.set_ylim(-0.02, 1.02)
        axis.set_xlabel("error rate of the noisy proposer")
        axis.set_ylabel("success rate")
    for index in range(len(problems), lines * columns):
        axes[index // columns][index % columns].axis("off")
    legend: dict[str, Any] = {}  # one entry per label over every panel
    for axis in axes.flat:
        for handle, label in zip(*axis.get_legend_handles_labels(), strict=True):
            legend.setdefault(label, handle)
    figure.legend(
        list(legend.values()), list(legend), loc="lower center", ncol=min(4, len(legend) or 1)
    )
    figure.tight_layout(rect=(0, 0.08, 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    plt.close(figure)
    return path


def _share(cell: tuple[int, int]) -> float:
    trials, successes = cell
    return successes / trials if trials else 0.0
