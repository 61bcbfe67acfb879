"""Solving a shipped problem as a user does, for the tests that check what its description
claims: ``stalm solve NAME --seed S --json`` in this process, the record replayed in a fresh
simulator, and the replay's plan run under the physics check."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pytest

from stalm.trial.replay import ReplayReport, replay_result_json
from stalm.world.physics_check import check_physics
from stalm.world.problem import Problem, load_problem
from tests.cli_runner import run_cli


@dataclass(frozen=True)
class ReplayedSolve:
    """A solved record of a shipped problem, replayed: its problem, the replay and the
    executed actions in words (``pick(jar)``, ``place(jar, on, table)``)."""

    problem: Problem
    replay: ReplayReport
    words: tuple[str, ...]


def solve_and_replay(
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    name: str,
    seed: int = 0,
    robot: str | None = None,
) -> ReplayedSolve:
    """``stalm solve NAME --seed SEED [--robot ROBOT]`` with its defaults; it must solve, and
    its record's plan must replay to the goal."""
    result = tmp_path / f"{name.lower()}-{robot}-{seed}.json"
    extra = ("--robot", robot) if robot is not None else ()
    code = run_cli(
        monkeypatch, "solve", name, "--seed", str(seed), "--json", str(result), "-q", *extra
    )
    assert code == 0
    record = json.loads(result.read_text())
    assert record["success"] is True, record["termination"]
    problem = load_problem(name) if robot is None else load_problem(name).with_robot(robot)
    replay = replay_result_json(problem, record)
    assert replay.reached_goal, replay.reason
    return ReplayedSolve(problem, replay, tuple(str(action) for action in replay.actions))


def assert_physics_passes(solve: ReplayedSolve) -> None:
    """Every object rests within the physics check's tolerance after each step settles."""
    report = check_physics(solve.problem, solve.replay.states, solve.words)
    assert report.passed, report.failure_line()
