"""No module of ``stalm/`` is over 400 lines, so each keeps one job a newcomer can read in one
sitting (issue 15); a module that outgrows the limit is split along its jobs instead."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MAX_LINES = 400


def module_lengths(package: Path) -> dict[str, int]:
    """Lines of every Python module under ``package``, by path from its parent."""
    return {
        path.relative_to(package.parent).as_posix(): len(
            path.read_text(encoding="utf-8").splitlines()
        )
        for path in sorted(package.rglob("*.py"))
    }


def too_long(package: Path) -> dict[str, int]:
    return {name: lines for name, lines in module_lengths(package).items() if lines > MAX_LINES}


def test_no_module_of_stalm_is_over_400_lines() -> None:
    lengths = module_lengths(ROOT / "stalm")
    assert len(lengths) > 100  # the package was read, subpackages included
    assert lengths["stalm/llm/reply_parser.py"] > 100
    assert too_long(ROOT / "stalm") == {}


def test_a_module_over_400_lines_is_named(tmp_path: Path) -> None:
    package = tmp_path / "stalm"
    (package / "world").mkdir(parents=True)
    (package / "world" / "long.py").write_text("x = 1\n" * 401, encoding="utf-8")
    (package / "short.py").write_text("x = 1\n" * 400, encoding="utf-8")
    assert too_long(package) == {"stalm/world/long.py": 401}
