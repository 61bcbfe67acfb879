"""``stalm view``: the page's data from a real result file, the page itself, and the command.

``data/p2_steps_result.json`` is a real result: STaLM solving P2 (seed 4) with the scripted
proposer of the planner tests offering the plan without its OPEN, so its first three real
steps are decided by the warm-started tree and the fourth by a plan Concretize took to the
goal. ``tests/planners/data/p2_result.json`` is an older file, without the per-step record.
"""

from __future__ import annotations

import copy
import itertools
import json
from pathlib import Path

import pytest

from stalm.viz.view_data import view_data
from stalm.viz.view_page import render_page
from tests.cli_runner import run_cli

DATA = Path(__file__).parent / "data"
STEPS_RESULT = json.loads((DATA / "p2_steps_result.json").read_text())
OLD_RESULT = json.loads(
    (Path(__file__).parent.parent / "planners" / "data" / "p2_result.json").read_text()
)


@pytest.fixture(scope="module")
def page_data(problems) -> dict:
    return view_data(problems["P2"], STEPS_RESULT, "p2_steps_result.json")


def test_the_frames_follow_the_replayed_plan_to_the_final_state(page_data) -> None:
    frames, scene = page_data["frames"], page_data["scene"]
    plan_length = STEPS_RESULT["plan_length"]
    assert frames["action"][0] == -1 and frames["action"][-1] == plan_length - 1
    assert sorted(set(frames["action"])) == list(range(-1, plan_length))
    assert len(frames["action"]) > 5 * plan_length  # the base drives, the arm moves
    bodies = scene["bodies"]
    assert {b["name"] for b in bodies} >= {"salter", "bottle1", "kitchen_door", "robot"}
    assert sum(b["count"] for b in bodies) == len(scene["moving"]["x"])
    assert all(len(poses) == 7 * len(bodies) for poses in frames["poses"])
    # the last frame puts the salter where the result's final state has it
    salter = next(i for i, b in enumerate(bodies) if b["name"] == "salter")
    final = STEPS_RESULT["final_state"]["poses"]["salter"]
    assert frames["poses"][-1][7 * salter : 7 * salter + 3] == pytest.approx(final[:3], abs=1e-3)
    start = STEPS_RESULT["initial_state"]["poses"]["salter"]
    assert frames["poses"][0][7 * salter : 7 * salter + 3] == pytest.approx(start[:3], abs=1e-3)
    # the static scene: floor, regions and walls as triangles with one colour per face
    for part in ("ground", "walls"):
        mesh = scene[part]
        assert len(mesh["i"]) == len(mesh["facecolor"]) > 12
        assert max(mesh["i"] + mesh["j"] + mesh["k"]) < len(mesh["x"])


def test_the_page_data_carries_the_plan_and_the_step_record(page_data) -> None:
    assert page_data["notes"] == []
    assert page_data["replay"]["reached_goal"]
    assert len(page_data["plan"]) == STEPS_RESULT["plan_length"]
    assert "placed at" in page_data["plan"][-1]["summary"]
    log = page_data["step_log"]
    assert log == STEPS_RESULT["details"]["step_log"]
    assert [step["decision"] for step in log] == ["best_q"] * 3 + ["concretize_goal"]
    assert all(step["decision"] in page_data["decisions"] for step in log)


def test_an_old_result_without_step_records_still_gives_a_page(problems) -> None:
    data = view_data(problems["P2"], OLD_RESULT)
    assert data["step_log"] is None
    assert any("no per-step record" in note for note in data["notes"])
    assert any("problem hash" in note for note in data["notes"])
    assert data["replay"]["reached_goal"] and len(data["frames"]["action"]) > 7
    page = render_page(data)
    assert "no per-step record" in page


def test_the_page_is_self_contained_and_text_from_the_file_cannot_break_out(page_data) -> None:
    page = render_page(page_data)
    assert "<script src" not in page and "<link" not in page  # nothing loaded from elsewhere
    assert 3e6 < len(page.encode()) < 8e6  # plotly.js (~4.8 MB) and the data
    hostile = copy.deepcopy(page_data)
    hostile["step_log"][0]["proposals"][0]["plans"][0]["detail"] = (
        "</script><script>window.pwned = 1</script><!--"
    )
    tampered = render_page(hostile)
    assert tampered.count("</script>") == page.count("</script>")
    assert "window.pwned" in tampered  # still there, as data


def test_stalm_view_writes_the_page_and_names_a_bad_file(monkeypatch, capsys, tmp_path) -> None:
    result = tmp_path / "p2.json"
    result.write_text(json.dumps(STEPS_RESULT))
    assert run_cli(monkeypatch, "view", str(result)) == 0
    page = tmp_path / "p2.html"
    assert page.stat().st_size > 3e6 and "wrote" in capsys.readouterr().out
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    assert run_cli(monkeypatch, "view", str(broken), "-o", str(tmp_path / "b.html")) == 2
    assert "broken.json" in capsys.readouterr().err


@pytest.mark.slow  # a solve: the scene check, roadmaps and 3 s of search (10-30 s)
def test_solve_writes_the_page_with_html(monkeypatch, capsys, tmp_path) -> None:
    page = tmp_path / "uct.html"
    code = run_cli(
        monkeypatch,
        "solve", "P2", "--planner", "uct", "--sims", "2", "--time-budget", "3",
        "--html", str(page),
    )  # fmt: skip
    assert code in (0, 1)  # three seconds rarely solve P2; the page is written either way
    assert page.stat().st_size > 3e6
    assert '"step_log":[{' in page.read_text()  # uct records its steps (with no proposals)


def test_a_plan_that_fails_its_replay_is_animated_up_to_the_failing_action(problems) -> None:
    forged = copy.deepcopy(STEPS_RESULT)
    forged["plan"][-1]["placement"][0] += 1.0  # the salter put down a metre from the hand
    data = view_data(problems["P2"], forged)
    last = len(forged["plan"])
    assert data["replay"]["failed_step"] == last - 1 and not data["replay"]["reached_goal"]
    assert any(f"fails at action {last}" in note for note in data["notes"])
    assert data["frames"]["action"][-1] == last - 2


def test_solve_refuses_an_html_path_it_cannot_write_before_planning(
    monkeypatch, capsys, tmp_path
) -> None:
    assert run_cli(monkeypatch, "solve", "P2", "--html", str(tmp_path)) == 2
    assert "--html" in capsys.readouterr().err


def test_the_timeline_is_in_seconds_of_the_robot_time_stalm_export_gives(problems, page_data):
    """Each frame's robot time comes from the plan timed as ``stalm export`` times it: it
    starts at 0, never runs back, ends with the plan, and falls inside its action's span."""
    from stalm.domain.schedule import schedule_plan
    from stalm.domain.serialize import action_from_json
    from stalm.world.robot_limits import panda_limits

    schedule = schedule_plan(
        [action_from_json(item) for item in STEPS_RESULT["plan"]], panda_limits()
    )
    frames, rows = page_data["frames"], page_data["plan"]
    times = frames["time"]
    assert len(times) == len(frames["action"]) and times[0] == 0.0
    assert all(b >= a for a, b in itertools.pairwise(times))
    assert times[-1] == pytest.approx(schedule.duration, abs=1e-3) and times[-1] > 30
    for action, time in zip(frames["action"], times, strict=True):
        if action >= 0:
            start, end = rows[action]["robot_time"]
            assert start - 1e-3 <= time <= end + 1e-3
    for row, timing in zip(rows, schedule.actions, strict=True):
        assert row["robot_time"] == pytest.approx([timing.start, timing.end], abs=1e-3)
    # the drive's last frame is at the time the arm starts, the action's last at its end
    first = [t for a, t in zip(frames["action"], times, strict=True) if a == 0]
    assert any(abs(t - schedule.actions[0].arm_start) < 1e-3 for t in first)
    assert first[-1] == pytest.approx(schedule.actions[0].end, abs=1e-3)
