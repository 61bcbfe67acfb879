"""The import contracts of ``pyproject.toml``, checked by import-linter, so ``pytest`` (and with
it ``.ci/run``) fails on an upward or sideways import or an import circle.

The layers, top to bottom: api and cli; experiments and viz; generate; planners; trial;
proposers; settings; llm and search; domain and predicates; motion; world; geometry.
Packages on one line may not import each other.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LINT = (
    "import sys; from importlinter.cli import lint_imports; "
    "sys.exit(lint_imports(config_filename=sys.argv[1], no_cache=True, no_logo=True))"
)


def _lint(source_root: Path) -> subprocess.CompletedProcess[str]:
    """import-linter on the ``stalm`` package found under ``source_root``."""
    env = {**os.environ, "PYTHONPATH": str(source_root)}
    return subprocess.run(
        [sys.executable, "-c", LINT, str(ROOT / "pyproject.toml")],
        cwd=source_root,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_the_package_keeps_its_import_contracts() -> None:
    result = _lint(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "2 kept, 0 broken" in result.stdout


def test_an_upward_a_sideways_import_and_a_circle_break_the_contracts(tmp_path: Path) -> None:
    shutil.copytree(ROOT / "stalm", tmp_path / "stalm", ignore=shutil.ignore_patterns("*.pyc"))

    def add_import(module: str, line: str) -> None:
        path = tmp_path / "stalm" / module
        path.write_text(path.read_text() + f"\n{line}\n")

    add_import("geometry/directions.py", "import stalm.trial.result")
    add_import("predicates/literals.py", "import stalm.domain.actions")
    add_import("cli/world_commands.py", "import stalm.cli.main")
    result = _lint(tmp_path)
    assert result.returncode == 1, result.stdout + result.stderr
    assert "stalm.geometry is not allowed to import stalm.trial" in result.stdout
    assert "stalm.predicates is not allowed to import stalm.domain" in result.stdout
    assert "No cycles are allowed in stalm.cli" in result.stdout
    assert "0 kept, 2 broken" in result.stdout
