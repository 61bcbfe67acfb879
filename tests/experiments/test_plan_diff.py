"""``stalm same-plans``: two results logs compared trial by trial, on the records of a real
run (issue 45's 60 trials of stalm-symbolic), changed here on purpose so that each verdict
must be found."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.experiments.plan_diff import compare_plans
from tests.cli_runner import run_cli

ROOT = Path(__file__).resolve().parents[2]
RUN = ROOT / "docs/results/issue45/stalm-symbolic-same-plans.jsonl"


@pytest.fixture(scope="module")
def records() -> list[dict]:
    return [json.loads(line) for line in RUN.read_text().splitlines()]


def _changed(records: list[dict]) -> list[dict]:
    """The run with one trial per kind of change: a joint moved 1e-3 rad in P1's trial 0, a
    failure in P2's trial 0, another seed in P3's trial 0, P4's trial 0 left out, a last
    action dropped in P5's trial 0, and 1e-7 added to a joint in P6's trial 0 (within the
    tolerance: still the same plan)."""
    after = copy.deepcopy(records)
    first = {r["problem"]: r for r in reversed(after) if r["trial"] == 0}
    first["P1"]["plan"][1]["arm_waypoints"][1][2] += 1e-3
    first["P2"]["success"] = False
    first["P3"]["seed"] += 1
    after.remove(first["P4"])
    first["P5"]["plan"].pop()
    first["P6"]["plan"][0]["arm_waypoints"][1][2] += 1e-7
    return after


def test_a_run_compared_with_itself_is_the_same_in_every_trial(records) -> None:
    comparison = compare_plans(records, records)
    assert comparison.all_same and len(comparison.trials) == 60
    assert set(comparison.counts()) == {("stalm-symbolic", f"P{i}") for i in range(1, 7)}


def test_each_change_is_found_and_said_where(records) -> None:
    comparison = compare_plans(records, _changed(records))
    assert not comparison.all_same
    odd = {
        (t.problem, t.trial): (t.verdict, t.why) for t in comparison.trials if t.verdict != "same"
    }
    assert set(odd) == {("P1", 0), ("P2", 0), ("P3", 0), ("P4", 0), ("P5", 0)}
    verdict, why = odd[("P1", 0)]
    assert verdict == "different" and why.startswith("action 2 (") and "/arm_waypoints[1][2]" in why
    assert odd[("P2", 0)] == ("different", "success True vs False")
    assert odd[("P3", 0)][0] == "not comparable" and odd[("P3", 0)][1].startswith("seed ")
    assert odd[("P4", 0)] == ("only before", "")
    assert odd[("P5", 0)][0] == "different" and "actions vs" in odd[("P5", 0)][1]
    counts = comparison.counts()
    assert counts[("stalm-symbolic", "P6")] == {"same": 10}
    assert counts[("stalm-symbolic", "P1")] == {"different": 1, "same": 9}
    # a looser tolerance takes the 1e-3 joint as the same
    loose = compare_plans(records, _changed(records), tolerance=1e-2)
    assert ("P1", 0) not in {(t.problem, t.trial) for t in loose.trials if t.verdict != "same"}


def test_the_command_exits_1_on_a_difference_and_names_the_trial(
    records, tmp_path, monkeypatch, capsys
) -> None:
    after = tmp_path / "after.jsonl"
    after.write_text("".join(json.dumps(r) + "\n" for r in _changed(records)))
    assert run_cli(monkeypatch, "same-plans", str(RUN), str(RUN)) == 0
    assert "| stalm-symbolic | P1 | 10 | 0 | 0 | 0 | 0 |" in capsys.readouterr().out
    assert run_cli(monkeypatch, "same-plans", str(RUN), str(after)) == 1
    shown = capsys.readouterr()
    assert "stalm-symbolic P4 trial 0: only before" in shown.out
    assert "| stalm-symbolic | P2 | 9 | 1 | 0 | 0 | 0 |" in shown.out
    assert "55 of 60 trials executed the same plan" in " ".join(shown.err.split())


def test_the_command_refuses_a_missing_file_and_a_negative_tolerance(
    tmp_path, monkeypatch, capsys
) -> None:
    assert run_cli(monkeypatch, "same-plans", str(RUN), str(tmp_path / "none.jsonl")) == 2
    assert "no results file at" in capsys.readouterr().err
    assert run_cli(monkeypatch, "same-plans", str(RUN), str(RUN), "--tolerance", "-1") == 2
    assert "--tolerance must be a number >= 0" in capsys.readouterr().err


def test_a_trial_only_after_and_a_plan_of_unnamed_steps() -> None:
    """Records as an older stalm or another tool may write them: no arm (the planner names the
    row), steps without a readable action."""
    first = {"key": "a", "planner": "uct", "problem": "X", "trial": 0, "seed": 1}
    before = [first | {"plan": [{}]}]
    after = [
        first | {"plan": [{"action": 1.0}]},
        {"key": "b", "planner": "uct", "problem": "X", "trial": 1, "seed": 2, "plan": []},
    ]
    trials = compare_plans(before, after).trials
    assert [(t.arm, t.trial, t.verdict) for t in trials] == [
        ("uct", 0, "different"),
        ("uct", 1, "only after"),
    ]
    assert trials[0].why.startswith("action 1 (?): ")


def _trial(**fields) -> dict:
    return {"key": "k", "arm": "uct", "problem": "X", "trial": 0, "seed": 1, "plan": [], **fields}


def test_how_a_trial_ended_and_what_it_ran_are_compared() -> None:
    """A timeout that became a crash, or a crash with another message, is a difference even
    with the same executed prefix; another problem file or budget ran something else."""

    def verdict(old: dict, new: dict) -> tuple[str, str]:
        (trial,) = compare_plans([old], [new]).trials
        return trial.verdict, trial.why

    timeout = _trial(termination="timeout", problem_sha="a", time_budget_s=10.0)
    assert verdict(timeout, timeout) == ("same", "")
    crash = _trial(termination="error", error="ValueError: x")
    assert verdict(timeout, crash) == ("different", "ended timeout vs error")
    other_crash = crash | {"error": "KeyError: y"}
    assert verdict(crash, other_crash) == (
        "different",
        "error 'ValueError: x' vs 'KeyError: y'",
    )
    forked = _trial(termination="error", error="a forked predicate worker (pid 4121) ended")
    assert verdict(forked, forked | {"error": "a forked predicate worker (pid 977) ended"})[0] == (
        "same"
    )
    in_folder = _trial(termination="error", error="OSError: /tmp/stalm-fd-4121-ab_c9/x")
    assert verdict(in_folder, in_folder | {"error": "OSError: /tmp/stalm-fd-977-zz1/x"})[0] == (
        "same"
    )
    assert verdict(timeout, timeout | {"problem_sha": "b"})[0] == "not comparable"
    unsaid = {k: v for k, v in timeout.items() if k != "time_budget_s"}
    assert verdict(timeout, unsaid) == ("same", "")  # a field only one record has: not compared
    assert verdict(timeout, timeout | {"time_budget_s": 20.0}) == (
        "not comparable",
        "time_budget_s 10.0 vs 20.0",
    )


def test_a_trial_run_twice_with_other_settings_or_a_malformed_record_is_refused() -> None:
    twice = [_trial(key="a"), _trial(key="b")]
    with pytest.raises(StalmError, match=r"old\.jsonl: uct ran trial 0 of X twice"):
        compare_plans(twice, [_trial()], names=("old.jsonl", "new.jsonl"))
    retried = [_trial(termination="error"), _trial(termination="goal")]  # one key: the newest
    assert compare_plans(retried, [_trial(termination="goal")]).all_same
    for bad in (_trial(trial="1"), _trial(trial=True), _trial(plan={"action": 1})):
        with pytest.raises(StalmError, match=r"new\.jsonl: the record of uct on X needs"):
            compare_plans([_trial()], [bad], names=("old.jsonl", "new.jsonl"))


def test_the_command_escapes_what_a_log_names_and_names_a_refused_log(
    tmp_path, monkeypatch, capsys
) -> None:
    odd = _trial(arm="a|b\x1b[31m", termination="goal")
    before, after = tmp_path / "before.jsonl", tmp_path / "after.jsonl"
    before.write_text(json.dumps(odd) + "\n")
    after.write_text(json.dumps(odd | {"termination": "timeout"}) + "\n")
    assert run_cli(monkeypatch, "same-plans", str(before), str(after)) == 1
    shown = capsys.readouterr().out
    assert "| a\\|b\\\\x1b[31m | X | 0 | 1 | 0 | 0 | 0 |" in shown and "\x1b" not in shown
    twice = [_trial(key="a", termination="goal"), _trial(key="b", termination="goal")]
    before.write_text("".join(json.dumps(r) + "\n" for r in twice))
    assert run_cli(monkeypatch, "same-plans", str(before), str(after)) == 2
    assert "ran trial 0 of X twice" in " ".join(capsys.readouterr().err.split())
