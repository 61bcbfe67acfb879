"""The shape of ``stalm/planners/``: the registry and one module per method of Tables 2 and 3,
each short, none importing the registry that imports them, none rebuilding the trial's
scaffold (:mod:`stalm.trial`)."""

from __future__ import annotations

import ast
from pathlib import Path

PLANNERS = Path(__file__).resolve().parents[2] / "stalm" / "planners"
MAX_MODULES = 12


def _imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return found


def test_no_planner_module_imports_the_registry_which_imports_them_directly() -> None:
    for path in PLANNERS.rglob("*.py"):
        if path.name == "registry.py":
            continue
        assert "stalm.planners.registry" not in _imported_modules(path), path
    registry = (PLANNERS / "registry.py").read_text()
    assert "importlib" not in registry
    assert "stalm.planners.llm_mcts" in _imported_modules(PLANNERS / "registry.py")


def test_the_online_scaffold_is_written_once() -> None:
    """The online methods (pddlstream/ runs offline, with its own loop) use the trial's."""
    for path in PLANNERS.glob("*.py"):
        text = path.read_text()
        assert "Episode.begin(" not in text and "def _say(" not in text, path.name
        assert "PredicateEngine(" not in text, f"{path.name} builds its own predicate engine"


def test_no_planner_module_is_over_400_lines() -> None:
    long = {
        str(path.relative_to(PLANNERS)): lines
        for path in PLANNERS.rglob("*.py")
        if (lines := len(path.read_text().splitlines())) > 400
    }
    assert long == {}


def test_planners_holds_at_most_twelve_modules() -> None:
    """A method that needs several modules (PDDLStream) keeps its own subpackage; the
    framework every method shares lives in settings/, proposers/ and trial/."""
    modules = sorted(path.name for path in PLANNERS.glob("*.py"))
    assert "registry.py" in modules and "stalm.py" in modules
    assert len(modules) <= MAX_MODULES, modules
