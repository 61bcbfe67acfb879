"""``stalm generate``: problems that load, pass the scene check and come with a witness that
replays; the same seed, the same file; a closed door and the grill trap in the witness."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.domain.outcome import Infeasibility
from stalm.errors import StalmError
from stalm.experiments.trap_check import trap_violations
from stalm.generate.arrange import Knobs
from stalm.generate.problem_maker import DECIMALS, generate_problem
from stalm.generate.suite import witness_path
from stalm.generate.suite_index import INDEX, read_suite
from stalm.motion.problem_check import problem_geometry_faults
from stalm.planners.registry import build_planner
from stalm.trial.replay import replay_plan
from stalm.world.problem import load_problem
from tests.cli_runner import run_cli
from tests.flat_settings import settings_of


@pytest.fixture(scope="module")
def suite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small suite made by the command: two sizes, two problems each."""
    folder = tmp_path_factory.mktemp("suite") / "tiny"
    with pytest.MonkeyPatch.context() as monkeypatch:
        args = ["generate", "--suite", "tiny", "--sizes", "6,10", "--per-size", "2"]
        assert run_cli(monkeypatch, *args, "--seed", "3", "-o", str(folder)) == 0
    return folder


def test_the_same_seed_gives_the_same_file() -> None:
    knobs = Knobs(objects=10, goals=2, occlusion_depth=1)
    first, again = (generate_problem(knobs, 11, "same") for _ in range(2))
    assert first.text == again.text
    other = generate_problem(knobs, 12, "same")
    assert other.text != first.text
    numbers = re.findall(r"-?\d+\.(\d+)", first.text)
    assert numbers and max(len(decimals) for decimals in numbers) <= DECIMALS


def test_every_problem_of_a_suite_loads_checks_and_replays_its_witness(
    suite: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    index = read_suite(suite)
    assert index.name == "tiny" and index.seed == 3
    assert [p.objects for p in index.problems] == [6, 6, 10, 10]
    for entry in index.problems:
        problem = load_problem(index.path(entry))
        assert len(problem.spec.objects) == entry.objects
        assert problem.spec.optimal_length == entry.optimal_length > 0
        assert problem_geometry_faults(problem) == []
        witness = json.loads((suite / entry.witness).read_text())
        assert witness["problem"] == problem.name  # as a solve of it names it (issue 42)
        assert witness["problem_hash"] == problem.content_hash
        assert witness["plan_length"] == entry.optimal_length
    moved = suite.parent / "moved-elsewhere"
    shutil.copytree(suite, moved)
    for entry in index.problems:
        (moved / entry.file).unlink()  # the witness carries its problem
    for entry in index.problems:
        assert run_cli(monkeypatch, "replay", str(moved / entry.witness)) == 0
        assert "the goal is reached" in capsys.readouterr().out


def test_making_a_suite_again_keeps_what_is_there(
    suite: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    before = {path.name: path.read_bytes() for path in suite.iterdir()}
    args = ["generate", "--suite", "tiny", "--sizes", "6,10", "--per-size", "2", "--seed", "3"]
    assert run_cli(monkeypatch, *args, "-o", str(suite)) == 0
    assert {path.name: path.read_bytes() for path in suite.iterdir()} == before


def test_a_closed_door_must_be_opened_first() -> None:
    generated = generate_problem(Knobs(objects=8, goals=1, occlusion_depth=1), 5, "door")
    witness = generated.witness
    assert witness.plan[0] == Open("kitchen_door")
    rooms = {r.name: r.room for r in generated.problem.spec.regions}
    goal = generated.problem.goal[0]
    start = next(o.on for o in generated.problem.spec.objects if o.name == goal.obj)
    assert rooms[start] != rooms[goal.ref]  # the goal lies across the doorway
    without_door = replay_plan(
        generated.problem, generated.problem.initial_state, list(witness.actions[1:])
    )
    assert not without_door.reached_goal and without_door.failed_step == 0
    no_door = generate_problem(Knobs(objects=8, goals=1, door=False), 5, "no_door")
    assert not no_door.problem.spec.doors
    assert not any(isinstance(step, Open) for step in no_door.witness.plan)


def test_the_trap_needs_its_order() -> None:
    """With --trap the grill goes last; placed first on the walled counter, it leaves no
    room for a can there (over several seeds)."""
    generated = generate_problem(Knobs(objects=10, goals=2, trap=True), 4, "trap")
    plan, states = generated.witness.plan, generated.witness.states
    grill = next(o.name for o in generated.problem.spec.objects if o.shape == "grill")
    assert plan[-2:] == (Pick(grill), Place(grill, "on", "walled_counter"))
    can = next(g.obj for g in generated.problem.goal if g.obj != grill)
    before_can = states[plan.index(Pick(can))]  # the can's chain cleared, nothing placed yet
    domain = Domain.create(generated.problem)
    try:
        rng = np.random.default_rng(0)
        state = before_can
        for step in (Pick(grill), Place(grill, "on", "walled_counter"), Pick(can)):
            for _ in range(5):
                action, outcome = domain.sample_and_step(state, step, rng)
                if outcome.feasible:
                    state = outcome.state
                    break
            assert action is not None and outcome.feasible, step
        for seed in range(6):
            drawn = domain.sample(
                state, Place(can, "on", "walled_counter"), np.random.default_rng(seed)
            )
            assert isinstance(drawn, Infeasibility), f"seed {seed}: the can fits beside the grill"
    finally:
        domain.close()


@pytest.mark.slow
@pytest.mark.parametrize("seed", [4, 5])
def test_a_solve_of_a_generated_trap_never_reaches_over_the_grill(seed) -> None:
    """The generated trap is P5's (the same walled counter and lidded grill), and is checked
    as P5's is: where a solve meets it. Before its grill had its lid (0.18 m), the arm could
    reach over it into the pocket behind."""
    generated = generate_problem(Knobs(objects=10, goals=2, trap=True), seed, "trap")
    problem = generated.problem
    planner = build_planner("stalm", settings_of(proposer="symbolic"))
    result = planner.solve(problem, seed=seed, time_budget_s=problem.spec.time_budget_s)
    assert result.success, result.termination
    report = replay_plan(problem, problem.initial_state, list(result.plan))
    assert report.reached_goal
    assert trap_violations(problem, report.states) == ()
    grill = next(o.name for o in problem.spec.objects if o.shape == "grill")
    assert result.plan[-1].discrete == Place(grill, "on", "walled_counter")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--goals", "5"], "--goals must be 1 to 4"),
        (["--trap", "--goals", "1"], "--goals must be 2 or 3"),
        (["--occlusion-depth", "4"], "--occlusion-depth must be 0 to 3"),
        (["--objects", "2", "--goals", "2"], "too few"),
        (["--door", "ajar"], "--door must be 'closed' or 'open'"),
        (["--layout", "castle"], "unknown layout 'castle'"),
    ],
)
def test_bad_knobs_are_one_line_naming_them(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    args: list[str],
    message: str,
) -> None:
    assert run_cli(monkeypatch, "generate", *args, "-o", str(tmp_path / "p.yaml")) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "p.yaml").exists()


def test_one_problem_and_its_witness_beside_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    out = tmp_path / "mine.yaml"
    assert run_cli(monkeypatch, "generate", "--objects", "7", "--seed", "2", "-o", str(out)) == 0
    assert witness_path(out).exists() and "witness" in capsys.readouterr().out
    assert load_problem(out).name == "mine"
    # the witness names its problem as a solve's result does, and carries it (issue 42)
    assert json.loads(witness_path(out).read_text())["problem"] == "mine"
    out.unlink()
    assert run_cli(monkeypatch, "replay", str(witness_path(out))) == 0


def test_a_suite_index_naming_files_elsewhere_is_refused(tmp_path: Path) -> None:
    (tmp_path / INDEX).write_text(
        json.dumps(
            {
                "suite_version": 2,
                "suite": "x",
                "seed": 0,
                "sizes": [1],
                "per_size": 1,
                "layout": "kitchen-hall",
                "knobs": {},
                "complete": True,
                "problems": [
                    {
                        "file": "../../etc/passwd",
                        "witness": "w.json",
                        "objects": 1,
                        "seed": 0,
                        "optimal_length": 1,
                        "sha256": "0" * 64,
                        "witness_sha256": "0" * 64,
                    }
                ],
            }
        )
    )
    with pytest.raises(StalmError, match="not a file name in the suite's folder"):
        read_suite(tmp_path)
    with pytest.raises(StalmError, match="cannot read the suite's index"):
        read_suite(tmp_path / "nowhere")


def test_the_scale_experiment_runs_a_suite_and_reports_by_size(
    suite: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    results = tmp_path / "scale.jsonl"
    args = ["experiment", "scale", "--suite", str(suite), "--planners", "stalm-symbolic"]
    args += ["--trials", "1", "--time-budget", "120", "--results", str(results)]
    assert run_cli(monkeypatch, *args) == 0
    records = [json.loads(line) for line in results.read_text().splitlines()]
    assert sorted((r["suite"], r["objects"]) for r in records) == [
        ("tiny", 6),
        ("tiny", 6),
        ("tiny", 10),
        ("tiny", 10),
    ]
    assert all(r["success"] for r in records)  # each has a witness: solvable
    out = capsys.readouterr().out
    assert "by number of objects" in out and "| stalm-symbolic | 2/2," in out
    assert (tmp_path / "scale-scale.png").exists() and (tmp_path / "scale-scale.svg").exists()
    assert run_cli(monkeypatch, *args) == 0  # resumes: nothing to run
    assert len(results.read_text().splitlines()) == 4


def test_scale_and_suite_go_together(
    suite: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run_cli(monkeypatch, "experiment", "scale", "--trials", "1") == 2
    assert "give --suite DIR" in capsys.readouterr().err
    assert run_cli(monkeypatch, "experiment", "table2", "--suite", str(suite)) == 2
    assert "--suite DIR goes with the scale experiment" in capsys.readouterr().err
