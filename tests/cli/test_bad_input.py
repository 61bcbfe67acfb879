"""Bad input on the command line is one ``error:`` line and exit code 2, never a traceback,
and is caught before any planning time is spent (issue 16, item 5)."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest

from tests.cli_runner import run_cli
from tests.llm.llm_doubles import ScriptedHTTPServerDouble, ScriptedReply

BINARY = bytes(range(256)) * 4


def one_error_line(err: str) -> str:
    """The error line of stderr, checking there is exactly one and no traceback."""
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, err
    return lines[0]


@pytest.fixture
def server() -> Iterator[ScriptedHTTPServerDouble]:
    double = ScriptedHTTPServerDouble()
    double.start()
    yield double
    double.stop()


@pytest.fixture(autouse=True)
def _no_llm_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("STALM_LLM", "STALM_LLM_BASE_URL", "STALM_LLM_MODEL", "OPENAI_API_KEY"):
        monkeypatch.delenv(name, raising=False)


def test_malformed_json_from_a_server_in_llm_check(monkeypatch, capsys, server) -> None:
    server.script = [ScriptedReply(body='{"choices": [', content_type="application/json")]
    assert run_cli(monkeypatch, "llm", "check", "--llm", f"{server.base_url}#m") == 2
    assert "malformed JSON" in one_error_line(capsys.readouterr().err)


def test_an_invalid_server_url(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "solve", "P2", "--llm", "http://[::1/v1#m") == 2
    assert "http://[::1/v1" in one_error_line(capsys.readouterr().err)
    assert run_cli(monkeypatch, "llm", "check", "--llm", "http://[::1/v1#m") == 2
    assert "base URL" in one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize(
    ("option", "value", "named"),
    [
        ("--seed", "-1", "--seed"),
        ("--sims", "0", "--sims"),
        ("--batch", "0", "--batch"),
        ("--time-budget", "nan", "--time-budget"),
        ("--time-budget", "inf", "--time-budget"),
        ("--time-budget", "-3", "--time-budget"),
        ("--time-budget", "0", "--time-budget"),
    ],
)
def test_numbers_out_of_range_for_solve(monkeypatch, capsys, option, value, named) -> None:
    budget = () if option == "--time-budget" else ("--time-budget", "3")
    assert run_cli(monkeypatch, "solve", "P2", "--planner", "uct", *budget, option, value) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("option", "value"), [("--time-budget", "nan"), ("--budget-scale", "nan"), ("--sims", "0")]
)
def test_numbers_out_of_range_for_experiment(monkeypatch, capsys, tmp_path, option, value) -> None:
    results = tmp_path / "r.jsonl"
    args = ("experiment", "table2", "--problems", "P2", "--planners", "uct", "--trials", "1")
    assert run_cli(monkeypatch, *args, "--results", str(results), option, value) == 2
    assert option in capsys.readouterr().err
    assert not results.exists()


def test_solve_json_naming_a_folder_fails_before_solving(monkeypatch, capsys, tmp_path) -> None:
    code = run_cli(
        monkeypatch,
        "solve",
        "P2",
        "--planner",
        "uct",
        "--time-budget",
        "30",
        "--json",
        str(tmp_path),
    )
    assert code == 2
    captured = capsys.readouterr()
    assert str(tmp_path) in one_error_line(captured.err)
    assert "plan (" not in captured.out  # nothing was solved


def test_solve_gif_under_a_file_fails_before_solving(monkeypatch, capsys, tmp_path) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    gif = blocker / "p2.gif"
    code = run_cli(
        monkeypatch, "solve", "P2", "--planner", "uct", "--time-budget", "30", "--gif", str(gif)
    )
    assert code == 2
    captured = capsys.readouterr()
    assert str(blocker) in one_error_line(captured.err)
    assert "plan (" not in captured.out


def test_a_result_that_cannot_be_written_goes_to_a_named_fallback(
    tmp_path, capsys, monkeypatch
) -> None:
    import tempfile

    from stalm.cli.solve_output import write_result_json

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the fallback lands here
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    written = write_result_json({"problem": "P2", "plan": []}, blocker / "r.json")
    assert written.parent == tmp_path and written.name.startswith("stalm-result-")
    assert json.loads(written.read_text()) == {"problem": "P2", "plan": []}
    assert str(written) in capsys.readouterr().err


def test_experiment_results_naming_a_folder(monkeypatch, capsys, tmp_path) -> None:
    args = ("experiment", "table2", "--problems", "P2", "--planners", "uct", "--trials", "1")
    assert run_cli(monkeypatch, *args, "--results", str(tmp_path)) == 2
    assert "folder" in one_error_line(capsys.readouterr().err)
    assert run_cli(monkeypatch, "report", str(tmp_path)) == 2
    one_error_line(capsys.readouterr().err)


def test_binary_problem_state_result_and_reply_files(monkeypatch, capsys, tmp_path) -> None:
    problem = tmp_path / "bin.yaml"
    problem.write_bytes(BINARY)
    assert run_cli(monkeypatch, "problems", "--file", str(problem)) == 2
    assert str(problem) in one_error_line(capsys.readouterr().err)
    state = tmp_path / "state.json"
    state.write_bytes(BINARY)
    assert (
        run_cli(monkeypatch, "render", "P2", "--state", str(state), "-o", str(tmp_path / "x.png"))
        == 2
    )
    assert str(state) in one_error_line(capsys.readouterr().err)
    assert run_cli(monkeypatch, "replay", str(state)) == 2
    assert str(state) in one_error_line(capsys.readouterr().err)
    assert run_cli(monkeypatch, "parse-reply", str(state), "--problem", "P2") == 2
    one_error_line(capsys.readouterr().err)


def test_a_truncated_roadmap_cache_file_is_rebuilt(tmp_path, monkeypatch, problems) -> None:
    import numpy as np

    from stalm.motion.roadmap import RoadmapSettings, cache_dir, load_or_build_roadmap
    from stalm.world.scene import Sim

    monkeypatch.setenv("STALM_CACHE_DIR", str(tmp_path))
    settings = RoadmapSettings(samples=15, neighbours=4)
    with Sim(problems["P2"].spec) as sim:
        first = load_or_build_roadmap(sim, frozenset(), settings)
        (path,) = cache_dir().glob("*.npz")
        for damage in (path.read_bytes()[:100], b"", BINARY):
            path.write_bytes(damage)
            again = load_or_build_roadmap(sim, frozenset(), settings)
            assert np.array_equal(again.nodes, first.nodes)
            assert again.adjacency == first.adjacency
        # a cache file whose edges name nodes that do not exist is damaged too
        nodes = np.zeros((2, 2))
        np.savez(path, nodes=nodes, edges=np.array([[0, 7]]), anchors=np.zeros((1, 2)))
        again = load_or_build_roadmap(sim, frozenset(), settings)
        assert again.adjacency == first.adjacency


@pytest.mark.parametrize(
    ("change", "named"),
    [
        (lambda s: s["poses"].update(ghost=[0.0, 0.0, 1.0, 0.0]), "ghost"),
        (lambda s: s["poses"].pop("salter"), "salter"),
        (lambda s: s["poses"].update(salter=[1e400, 0.0, 1.0, 0.0]), "poses.salter"),
        (lambda s: s["robot"].update(arm=[0.0] * 6), "robot.arm"),
        (lambda s: s.update(open_doors=["back_door"]), "back_door"),
        (lambda s: s.update(held={"obj": ["x"]}), "held"),
    ],
)
def test_state_files_that_do_not_fit_the_problem(
    monkeypatch, capsys, tmp_path, problems, change, named
) -> None:
    state = problems["P2"].initial_state.to_json()
    change(state)
    path = tmp_path / "state.json"
    path.write_text(json.dumps(state))
    assert (
        run_cli(monkeypatch, "render", "P2", "--state", str(path), "-o", str(tmp_path / "x.png"))
        == 2
    )
    assert named in one_error_line(capsys.readouterr().err)


def test_llm_check_against_a_hanging_server_ends_at_its_timeout(
    monkeypatch, capsys, server
) -> None:
    import time

    from tests.llm.llm_doubles import chat_completion

    server.script = [ScriptedReply(body=chat_completion(["late"]), delay_s=60)]
    started = time.monotonic()
    args = ("llm", "check", "--llm", f"{server.base_url}#m", "--timeout", "1")
    assert run_cli(monkeypatch, *args) == 2
    assert time.monotonic() - started < 5
    assert "no answer within 1 s" in one_error_line(capsys.readouterr().err)
