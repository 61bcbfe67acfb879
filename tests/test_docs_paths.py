"""The architecture page's "How it is built" section names files that exist, and names every
planner's."""

from __future__ import annotations

import re
from pathlib import Path

from stalm.planners import iterative_replanning, llm_mcts, saycan, stalm, uct
from stalm.planners.pddlstream import planner as pddlstream

ROOT = Path(__file__).resolve().parents[1]
PLANNERS = (stalm, uct, saycan, iterative_replanning, llm_mcts, pddlstream)
"""The modules of every planner of the registry (its parts and ablations live with them)."""


def named_paths() -> set[str]:
    """The backticked paths of the section (a token with a '/' or a file suffix), outside its
    fenced blocks."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    section = text.split("\n## How it is built\n", 1)[1].split("\n## ", 1)[0]
    prose = re.sub(r"```.*?```", "", section, flags=re.DOTALL)
    tokens = re.findall(r"`([^`\s]+)`", prose)
    return {t for t in tokens if "/" in t or re.search(r"\.(py|toml|md|js)$", t)}


def test_every_path_the_section_names_exists() -> None:
    paths = named_paths()
    assert len(paths) >= 40  # the table is there and was read
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert missing == []


def test_the_section_names_the_file_of_every_planner() -> None:
    paths = named_paths()
    for planner in PLANNERS:
        module = planner.__file__
        assert module is not None
        assert Path(module).resolve().relative_to(ROOT).as_posix() in paths, planner.__name__
