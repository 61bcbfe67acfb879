"""P1-P6 ship inside the package and are found by name after any install, from any folder;
``$STALM_PROBLEMS_DIR`` adds problems or overrides them by name (issue 42, item 1).

A wheel installs ``stalm/`` into site-packages and nothing beside it: a problem looked up two
folders above the package was found only in a checkout. ``.ci/run`` installs the built wheel
into a fresh venv and solves P2 there; these tests keep the parts that a checkout can show.
"""

from __future__ import annotations

import glob
import tomllib
from pathlib import Path

import pytest
import yaml

import stalm
from stalm.errors import StalmError
from stalm.world import problem as problem_module
from stalm.world.problem import PROBLEMS_ENV, available_problems, load_problem
from tests.cli.test_bad_input import one_error_line
from tests.cli_runner import run_cli

PACKAGE = Path(stalm.__file__).resolve().parent
ROOT = PACKAGE.parent
NAMES = ("BOX1", "MESH1", "MOVE2", "MUG1", "P1", "P2", "P3", "P4", "P5", "P6", "TABLE1")


@pytest.fixture(autouse=True)
def _elsewhere(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Run from a folder outside the checkout, without a folder of one's own problems."""
    monkeypatch.delenv(PROBLEMS_ENV, raising=False)
    monkeypatch.chdir(tmp_path)


def test_the_named_problems_are_found_inside_the_package_from_any_folder() -> None:
    for name in NAMES:
        problem = load_problem(name)
        assert problem.name == name
        assert Path(problem.source).resolve().is_relative_to(PACKAGE), problem.source
    assert [path.stem.upper() for path in available_problems()] == list(NAMES)


def test_the_package_data_globs_carry_every_problem_file_into_the_wheel() -> None:
    """setuptools expands each package-data pattern with ``glob(recursive=True)`` under the
    package: every file of ``stalm/problems`` must be matched by one, or a wheel lacks it."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = config["tool"]["setuptools"]["package-data"]["stalm"]
    shipped = {
        Path(match).resolve()
        for pattern in patterns
        for match in glob.glob(str(PACKAGE / pattern), recursive=True)
    }
    folder = PACKAGE / "problems"
    files = {path.resolve() for path in folder.rglob("*") if path.is_file()}
    assert {f"{name.lower()}.yaml" for name in NAMES} <= {path.name for path in files}
    assert folder / "layouts" / "clutter35.yaml" in files
    assert files - shipped == set()
    assert not list(folder.rglob("*.py"))  # data, not a package


def test_a_folder_in_the_environment_adds_problems_and_overrides_by_name(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    data = yaml.safe_load((PACKAGE / "problems" / "p2.yaml").read_text(encoding="utf-8"))
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "kitchen.yaml").write_text(yaml.safe_dump({**data, "name": "Kitchen"}))
    (mine / "p2.yaml").write_text(yaml.safe_dump({**data, "horizon": 7}))
    monkeypatch.setenv(PROBLEMS_ENV, str(mine))
    assert load_problem("kitchen").name == "Kitchen"
    assert load_problem("P2").horizon == 7
    assert Path(load_problem("P2").source).parent == mine
    assert load_problem("P1").name == "P1"  # the shipped ones are still there
    names = [path.stem.upper() for path in available_problems()]
    assert names == sorted(["KITCHEN", *NAMES])


def test_an_unknown_name_says_where_it_was_looked_for(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv(PROBLEMS_ENV, str(tmp_path))
    with pytest.raises(StalmError) as error:
        load_problem("P9")
    text = str(error.value)
    assert str(tmp_path) in text and str(PACKAGE / "problems") in text
    assert "P1, P2, P3, P4, P5, P6" in text
    monkeypatch.setenv(PROBLEMS_ENV, str(tmp_path / "gone"))
    with pytest.raises(StalmError, match=f"{PROBLEMS_ENV}.*gone is not a folder"):
        load_problem("P2")


def test_no_problems_found_is_an_error_not_an_empty_table(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setattr(problem_module, "shipped_problems_dir", lambda: empty)
    assert run_cli(monkeypatch, "problems") == 2
    captured = capsys.readouterr()
    assert "no problem files in" in one_error_line(captured.err)
    assert "stalm problems" not in captured.out + captured.err  # no table's title
