"""What ``stalm generate`` writes, and where: a suite's name is an identifier, never a path; a
folder holding another suite is refused (or replaced whole with ``--replace``); the index
records each problem's and witness's hash, and ``experiment scale`` refuses a file that
differs; output paths are checked before any generation, and a problem is written with its
witness or not at all."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.experiments.suites import build_plan
from stalm.generate.arrange import Knobs
from stalm.generate.problem_maker import generate_problem
from stalm.generate.suite import generate_suite, witness_path, write_generated
from stalm.generate.suite_index import INDEX, read_suite
from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli

SMALL = ["--sizes", "6", "--per-size", "1"]


def _files(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (relative name -> bytes)."""
    return {
        str(path.relative_to(folder)): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def no_generation(monkeypatch: pytest.MonkeyPatch) -> None:
    """A test double for the generator: any call fails the test, so a refusal is shown to
    come before the work."""

    def generation_not_expected(*args: object, **kwargs: object) -> None:
        raise AssertionError("generated a problem although the output was refused")

    monkeypatch.setattr("stalm.generate.problem_maker.generate_problem", generation_not_expected)
    monkeypatch.setattr("stalm.generate.suite.generate_problem", generation_not_expected)


# ---------------------------------------------------------------------------------------------
# a suite's name is an identifier


@pytest.mark.parametrize("name", ["ABS", "../esc", "a/b", "", ".", "..", "x y", "-x", "x\n"])
def test_a_suite_name_that_is_a_path_is_refused_before_any_work(
    monkeypatch, capsys, tmp_path: Path, no_generation, name: str
) -> None:
    if name == "ABS":
        name = str(tmp_path / "abs" / "x")
    out = tmp_path / "sub" / "deeper"
    code = run_cli(monkeypatch, "generate", "--suite", name, *SMALL, "-o", str(out))
    assert code == 2
    assert "--suite" in one_error_line(capsys.readouterr().err)
    assert list(tmp_path.rglob("*")) == []  # nothing written, inside -o or out of it


def test_generate_suite_refuses_a_path_as_name_too(tmp_path: Path) -> None:
    with pytest.raises(StalmError, match="not a path"):
        generate_suite("../x", (6,), 1, 0, tmp_path / "s", Knobs(6, 1, 1))
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------------------------
# suites that cannot be mixed


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A one-problem suite ``a`` (6 objects, seed 1), never modified by the tests."""
    folder = tmp_path_factory.mktemp("made") / "suite"
    generate_suite("a", (6,), 1, 1, folder, Knobs(6, 1, 1))
    return folder


def _copy(made: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "suite"
    folder.mkdir()
    for name, data in _files(made).items():
        (folder / name).write_bytes(data)
    return folder


def test_the_index_records_each_problems_hash_and_its_witnesss(made: Path) -> None:
    data = json.loads((made / INDEX).read_text())
    (entry,) = data["problems"]
    assert entry["sha256"] == _sha(made / entry["file"])
    assert entry["witness_sha256"] == _sha(made / entry["witness"])
    assert data["complete"] is True
    (problem,) = read_suite(made).problems
    assert (problem.sha256, problem.witness_sha256) == (entry["sha256"], entry["witness_sha256"])


@pytest.mark.parametrize(
    "other", [["--seed", "2"], ["--sizes", "7"], ["--goals", "2"], ["--suite", "b"]]
)
def test_generating_another_suite_into_its_folder_is_refused(
    monkeypatch, capsys, tmp_path: Path, made: Path, no_generation, other: list[str]
) -> None:
    folder = _copy(made, tmp_path)
    before = _files(folder)
    args = ["generate", "--suite", "a", *SMALL, "--seed", "1", "--goals", "1"]
    code = run_cli(monkeypatch, *args, *other, "-o", str(folder))
    assert code == 2
    line = one_error_line(capsys.readouterr().err)
    assert "--replace" in line and str(folder) in line
    assert _files(folder) == before


def test_replace_makes_the_new_suite_whole_and_removes_the_old(
    monkeypatch, tmp_path: Path, made: Path
) -> None:
    folder = _copy(made, tmp_path)
    (folder / "notes.txt").write_text("mine")  # not the suite's: left alone
    args = ["generate", "--suite", "b", *SMALL, "--seed", "2", "--goals", "1"]
    assert run_cli(monkeypatch, *args, "-o", str(folder), "--replace") == 0
    suite = read_suite(folder)
    assert (suite.name, suite.seed) == ("b", 2)
    assert sorted(_files(folder)) == ["b-000.witness.json", "b-000.yaml", INDEX, "notes.txt"]


def test_an_interrupted_suite_is_not_run_and_the_same_command_finishes_it(
    tmp_path: Path, made: Path
) -> None:
    def interrupt(message: str) -> None:
        raise KeyboardInterrupt

    folder = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt):
        generate_suite("a", (6,), 2, 1, folder, Knobs(6, 1, 1), progress=interrupt)
    with pytest.raises(StalmError, match="not finished"):
        read_suite(folder)  # an experiment never runs half a suite
    # stopped after its first problem: the made suite's (a problem's seed is the suite's seed
    # and its number), under an index that says two problems, unfinished
    folder = _copy(made, tmp_path)
    data = json.loads((folder / INDEX).read_text())
    (folder / INDEX).write_text(json.dumps(data | {"per_size": 2, "complete": False}))
    first = (folder / "a-000.yaml").stat().st_mtime_ns
    calls: list[str] = []
    suite = generate_suite("a", (6,), 2, 1, folder, Knobs(6, 1, 1), progress=calls.append)
    assert len(calls) == 1 and calls[0].startswith("a-001.yaml")  # only the missing one
    assert (folder / "a-000.yaml").stat().st_mtime_ns == first
    assert len(suite.problems) == 2 and read_suite(folder).problems == suite.problems


def test_an_edited_problem_stops_the_same_command_again(tmp_path: Path, made: Path) -> None:
    folder = _copy(made, tmp_path)
    with (folder / "a-000.yaml").open("a") as handle:
        handle.write("# edited\n")
    with pytest.raises(StalmError, match=r"a-000\.yaml.*--replace"):
        generate_suite("a", (6,), 1, 1, folder, Knobs(6, 1, 1))


@pytest.mark.parametrize("edited", ["a-000.yaml", "a-000.witness.json"])
def test_scale_refuses_a_file_that_differs_from_the_index(
    monkeypatch, capsys, tmp_path: Path, made: Path, edited: str
) -> None:
    folder = _copy(made, tmp_path)
    text = (folder / edited).read_text()
    (folder / edited).write_text(text.replace("\n", "\n\n", 1))  # the same data, other bytes
    with pytest.raises(StalmError, match=f"{edited}.*differs from the suite's index"):
        build_plan("scale", suite=folder, trials=1)
    results = tmp_path / "r.jsonl"
    args = ["experiment", "scale", "--suite", str(folder), "--trials", "1"]
    assert run_cli(monkeypatch, *args, "--results", str(results)) == 2
    assert edited in one_error_line(capsys.readouterr().err)
    assert not results.exists()


def test_scale_refuses_an_index_whose_object_count_is_not_the_problems(
    tmp_path: Path, made: Path
) -> None:
    folder = _copy(made, tmp_path)
    data = json.loads((folder / INDEX).read_text())
    data["problems"][0]["objects"] = 7
    (folder / INDEX).write_text(json.dumps(data))
    with pytest.raises(StalmError, match="objects"):
        build_plan("scale", suite=folder, trials=1)


def test_an_index_made_before_hashes_is_refused_naming_the_fix(tmp_path: Path, made: Path) -> None:
    folder = _copy(made, tmp_path)
    data = json.loads((folder / INDEX).read_text())
    data["suite_version"] = 1
    for entry in data["problems"]:
        del entry["sha256"], entry["witness_sha256"]
    (folder / INDEX).write_text(json.dumps(data))
    with pytest.raises(StalmError, match="--replace"):
        read_suite(folder)


# ---------------------------------------------------------------------------------------------
# output paths checked before the work; a problem and its witness together or neither


def _generate_one(monkeypatch, capsys, out: Path) -> str:
    code = run_cli(monkeypatch, "generate", "--objects", "6", "--goals", "1", "-o", str(out))
    err = capsys.readouterr().err
    assert code == 2, err
    return one_error_line(err)


def test_a_parent_that_is_a_file_is_refused_before_generating(
    monkeypatch, capsys, tmp_path: Path, no_generation
) -> None:
    (tmp_path / "plain").write_text("x")
    line = _generate_one(monkeypatch, capsys, tmp_path / "plain" / "x.yaml")
    assert "is a file" in line


def test_a_folder_named_like_the_problem_is_refused_before_generating(
    monkeypatch, capsys, tmp_path: Path, no_generation
) -> None:
    (tmp_path / "x.yaml").mkdir()
    assert "is a folder" in _generate_one(monkeypatch, capsys, tmp_path / "x.yaml")


def test_a_folder_where_the_witness_goes_is_refused_before_generating(
    monkeypatch, capsys, tmp_path: Path, no_generation
) -> None:
    (tmp_path / "x.witness.json").mkdir()
    line = _generate_one(monkeypatch, capsys, tmp_path / "x.yaml")
    assert "x.witness.json" in line and "is a folder" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.witness.json"]


def test_a_folder_that_cannot_be_written_is_refused_before_generating(
    monkeypatch, capsys, no_generation
) -> None:
    line = _generate_one(monkeypatch, capsys, Path("/proc/stalm-nowhere/x.yaml"))
    assert "cannot write" in line


def test_a_suite_folder_that_is_a_file_is_refused_before_generating(
    monkeypatch, capsys, tmp_path: Path, no_generation
) -> None:
    (tmp_path / "s").write_text("x")
    code = run_cli(monkeypatch, "generate", "--suite", "s", *SMALL, "-o", str(tmp_path / "s"))
    assert code == 2
    assert "is a file" in one_error_line(capsys.readouterr().err)


def test_a_folder_where_a_suite_file_goes_is_refused_before_generating(
    monkeypatch, capsys, tmp_path: Path, no_generation
) -> None:
    (tmp_path / "s" / "s-000.witness.json").mkdir(parents=True)
    code = run_cli(monkeypatch, "generate", "--suite", "s", *SMALL, "-o", str(tmp_path / "s"))
    assert code == 2
    assert "s-000.witness.json" in one_error_line(capsys.readouterr().err)


def test_the_problem_and_its_witness_are_written_together_or_neither(tmp_path: Path) -> None:
    generated = generate_problem(Knobs(6, 1, 1), 0, "pair")
    out = tmp_path / "pair.yaml"
    out.write_text("the old problem\n")
    witness_path(out).mkdir()  # appears after the checks: the write itself must hold
    with pytest.raises(StalmError, match="pair"):
        write_generated(generated, out)
    assert out.read_text() == "the old problem\n"  # kept as it was
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pair.witness.json", "pair.yaml"]
    witness_path(out).rmdir()
    write_generated(generated, out)
    assert out.read_text() == generated.text
    assert json.loads(witness_path(out).read_text())["problem"] == "pair"


def test_suite_files_no_index_names_are_refused_before_generating(
    monkeypatch, capsys, tmp_path: Path, no_generation
) -> None:
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "s-000.yaml").write_text("someone's problem\n")
    code = run_cli(monkeypatch, "generate", "--suite", "s", *SMALL, "-o", str(tmp_path / "s"))
    assert code == 2
    line = one_error_line(capsys.readouterr().err)
    assert "s-000.yaml" in line and "no suite index names it" in line
    assert (tmp_path / "s" / "s-000.yaml").read_text() == "someone's problem\n"


def test_an_unreadable_index_is_refused_and_replace_goes_with_suite(
    monkeypatch, capsys, tmp_path: Path, no_generation
) -> None:
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / INDEX).write_text("{not json")
    code = run_cli(monkeypatch, "generate", "--suite", "s", *SMALL, "-o", str(tmp_path / "s"))
    assert code == 2
    assert "--replace" in one_error_line(capsys.readouterr().err)
    code = run_cli(monkeypatch, "generate", "--replace", "-o", str(tmp_path / "p.yaml"))
    assert code == 2
    assert "--replace goes with --suite" in one_error_line(capsys.readouterr().err)


def test_a_problem_edited_between_reading_the_index_and_the_run_is_refused(
    tmp_path: Path, made: Path
) -> None:
    from stalm.experiments.suites import trial_specs

    folder = _copy(made, tmp_path)
    plan = build_plan("scale", suite=folder, trials=1, planners=("uct",))
    with (folder / "a-000.yaml").open("a") as handle:
        handle.write("# edited after the check\n")
    with pytest.raises(StalmError, match="differs from the suite's index"):
        trial_specs(plan)


def test_a_budget_beyond_what_a_record_holds_is_refused(made: Path) -> None:
    from stalm.experiments.suites import trial_specs

    plan = build_plan("scale", suite=made, trials=1, planners=("uct",), time_budget_s=2e7)
    with pytest.raises(StalmError, match="more than a record holds"):
        trial_specs(plan)


def test_a_suite_under_a_file_or_without_problems_is_refused(tmp_path: Path) -> None:
    (tmp_path / "plain").write_text("x")
    with pytest.raises(StalmError, match="is a file, not a folder"):
        generate_suite("s", (6,), 1, 0, tmp_path / "plain" / "s", Knobs(6, 1, 1))
    with pytest.raises(StalmError, match="--per-size of at least 1"):
        generate_suite("s", (6,), 0, 0, tmp_path / "s", Knobs(6, 1, 1))


def test_write_together_removes_a_new_file_when_its_partner_fails(tmp_path: Path) -> None:
    from stalm.files import write_together

    (tmp_path / "b.json").mkdir()
    with pytest.raises(OSError):
        write_together([(tmp_path / "a.yaml", "a\n"), (tmp_path / "b.json", "{}\n")])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.json"]  # no a.yaml, no temporary


def test_a_negative_suite_seed_is_one_line_before_any_work(tmp_path: Path) -> None:
    with pytest.raises(StalmError, match="--seed must be a non-negative integer, got -1"):
        generate_suite("a", (6,), 1, -1, tmp_path / "s", Knobs(6, 1, 1))
    assert not (tmp_path / "s").exists()
