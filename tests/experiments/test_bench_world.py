"""`stalm bench world`: the operator timings and what it says while it works."""

from __future__ import annotations

from stalm.experiments.bench_world import bench_problem


def test_bench_world_times_each_operator_and_says_what_it_is_doing() -> None:
    said: list[str] = []
    row = bench_problem("P2", attempts=3, seed=0, progress=said.append)
    assert said[0].startswith("P2: base roadmaps")
    assert any("operator attempts" in message for message in said)
    assert said[-1] == "P2: raw collision checks"
    for operator in ("pick", "place"):
        summary = row[operator]
        assert isinstance(summary, dict) and summary["n"] >= 3
        assert 0.0 <= summary["feasible_rate"] <= 1.0 and summary["median_ms"] > 0
    assert isinstance(row["raw_checks_per_second"], float) and row["raw_checks_per_second"] > 0
