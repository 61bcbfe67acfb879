"""The scale experiment's report: success rate and mean time of successes by object count.

Records of ``stalm experiment scale`` carry ``objects`` (the problem's number of movable
objects) and ``suite``. Per planner row and object count: trials, successes and the mean time
of the successes; and the slope of log(mean time) against log(objects), fitted by least squares
over the sizes with a success (1: time grows linearly with the objects, 2: quadratically).
"""

from __future__ import annotations

import math
import statistics
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stalm.experiments.markdown_cells import cell as markdown_cell


@dataclass(frozen=True)
class ScaleCell:
    trials: int
    successes: int
    mean_success_time_s: float | None


def object_count(record: dict[str, Any]) -> int | None:
    """The record's ``objects`` if it is a count (a whole number of at least 1), else None.
    Records are checked as they are read (:func:`~stalm.experiments.results_log.
    record_problem`); this keeps records handed in by other code from a log of 0 or less."""
    objects = record.get("objects")
    if isinstance(objects, bool) or not isinstance(objects, int) or objects < 1:
        return None
    return objects


def has_sizes(records: Iterable[dict[str, Any]]) -> bool:
    """Do the records come from a scale experiment (they carry ``objects``)?"""
    return any(object_count(r) is not None for r in records)


def scale_cells(records: Iterable[dict[str, Any]]) -> dict[tuple[str, int], ScaleCell]:
    """(row, object count) -> its cell; records without a count of ``objects`` are left out."""
    grouped: dict[tuple[str, int], list[dict[str, Any]]] = defaultdict(list)
    for record in records:
        objects = object_count(record)
        if objects is not None:
            grouped[(str(record["arm"]), objects)].append(record)
    cells = {}
    for key, group in grouped.items():
        times = [float(r["time_s"]) for r in group if r.get("success")]
        cells[key] = ScaleCell(len(group), len(times), statistics.mean(times) if times else None)
    return cells


def slope(points: list[tuple[int, float]]) -> float | None:
    """Least-squares slope of log(time) against log(objects) (None: fewer than two sizes)."""
    if len({n for n, _ in points}) < 2:
        return None
    xs = [math.log(n) for n, _ in points]
    ys = [math.log(max(t, 1e-3)) for _, t in points]
    mean_x, mean_y = statistics.mean(xs), statistics.mean(ys)
    spread = sum((x - mean_x) ** 2 for x in xs)
    return sum((x - mean_x) * (y - mean_y) for x, y in zip(xs, ys, strict=True)) / spread


def markdown_scale(cells: dict[tuple[str, int], ScaleCell]) -> str:
    rows = sorted({row for row, _ in cells})
    sizes = sorted({size for _, size in cells})
    header = "| row | " + " | ".join(f"{n} objects" for n in sizes) + " | slope (log-log) |"
    lines = [header, "| --- |" + " --- |" * (len(sizes) + 1)]
    for row in rows:
        texts, points = [], []
        for size in sizes:
            cell = cells.get((row, size))
            if cell is None:
                texts.append("–")
                continue
            time = (
                "t/o" if cell.mean_success_time_s is None else f"{cell.mean_success_time_s:.1f} s"
            )
            texts.append(f"{cell.successes}/{cell.trials}, {time}")
            if cell.mean_success_time_s is not None:
                points.append((size, cell.mean_success_time_s))
        fitted = slope(points)
        texts.append("–" if fitted is None else f"{fitted:.2f}")
        lines.append(f"| {markdown_cell(row)} | " + " | ".join(texts) + " |")
    return "\n".join(lines) + "\n"


def _minor_seconds(value: float, _: object) -> str:
    """Minor ticks of the log time axis: 2, 3 and 5 of each decade written, the rest not."""
    leading = f"{value:.0e}"[0]
    return f"{value:g}" if leading in "235" else ""


ROW_MARKERS = ("o", "s", "^", "D", "v", "P")
ROW_LINES = ("-", "--", "-.", ":")


def plot_scale(cells: dict[tuple[str, int], ScaleCell], path: Path) -> Path:
    """Success rate (left) and mean time of successes, log-log (right), by object count."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, NullFormatter

    figure, (rate_axis, time_axis) = plt.subplots(1, 2, figsize=(10, 4))
    legend: list[tuple[Any, str]] = []  # one entry a row: its time line (with the slope), if any
    for index, row in enumerate(sorted({r for r, _ in cells})):
        # rows that solve every problem lie on one line at 1.0: each row gets its own marker
        # and dashes, and a smaller marker than the row before, so none hides another
        style = {
            "marker": ROW_MARKERS[index % len(ROW_MARKERS)],
            "linestyle": ROW_LINES[index % len(ROW_LINES)],
            "markersize": max(3.0, 9.0 - 1.5 * index),
        }
        sizes = sorted(size for r, size in cells if r == row)
        rates = [cells[(row, n)].successes / cells[(row, n)].trials for n in sizes]
        (line,) = rate_axis.plot(sizes, rates, **style)
        timed = [(n, cells[(row, n)].mean_success_time_s) for n in sizes]
        points = [(n, t) for n, t in timed if t is not None]
        label = row
        if points:
            fitted = slope(points)
            label = row if fitted is None else f"{row} (slope {fitted:.2f})"
            time_axis.plot([n for n, _ in points], [t for _, t in points], **style)
        legend.append((line, label))
    rate_axis.set(xlabel="movable objects", ylabel="success rate", ylim=(-0.05, 1.05))
    rate_axis.set_xscale("log", base=2)
    time_axis.set(xlabel="movable objects", ylabel="mean time of successes (s)")
    time_axis.set_xscale("log", base=2)
    time_axis.set_yscale("log")
    time_axis.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))  # 20
    time_axis.yaxis.set_minor_formatter(FuncFormatter(_minor_seconds))
    every_size = sorted({size for _, size in cells})
    for axis in (rate_axis, time_axis):
        axis.set_xticks(every_size, [str(size) for size in every_size])  # 64, not 2^6
        axis.xaxis.set_minor_formatter(NullFormatter())
        axis.grid(True, which="both", alpha=0.3)
    # one legend below both plots, each row with its slope: inside either plot it hid a line
    if legend:
        figure.legend(*zip(*legend, strict=True), loc="lower center", ncol=2, fontsize=8)
    figure.tight_layout(rect=(0, 0.06 * (1 + (len(legend) + 1) // 2), 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    plt.close(figure)
    return path
