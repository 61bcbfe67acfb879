"""Every code block of the README and of the docs pages (docs/*.md) runs or is checked.

- ``python`` blocks run as written, each in a fresh namespace (the ones that solve a problem
  are marked slow);
- ``bash`` blocks are checked without running them (some take minutes): every ``stalm``
  command names a command that exists, with options it takes and values of their types (Click
  parses it as the command line would), and every ``--set KEY=VALUE`` is a setting; ``python
  FILE`` names a file of the repository, and any other program is one the docs may name;
- ``yaml`` blocks parse, and one that is a problem file loads as one (with the scene check);
  ``text`` blocks (printed output, trees) are shown, not run.

A block without a language is refused, so a new block is never left unchecked by accident.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pytest
import typer
import yaml

from stalm.api import PlanResult, RunSettings, with_overrides
from stalm.cli.main import app

ROOT = Path(__file__).resolve().parents[1]
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
LANGUAGES = {"python", "bash", "yaml", "text"}
# Typer parses with its own copy of Click: its exceptions, found through one Typer exports
USAGE_ERROR = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")
CLICK_EXCEPTION = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")
PROGRAMS = {
    "stalm",
    "pip",
    "pytest",
    "python",
    "python3",
    "mkdocs",
    "export",
    ".",
    "ollama",
    "vllm",
    "llama-server",
    "apt-get",
    "bash",
}
"""What a bash block may run besides stalm: installing, testing, building these docs, and the
language-model servers the docs name."""
_FENCE = re.compile(r"^( *)```(\S*)\n(.*?)^\1```$", re.DOTALL | re.MULTILINE)


@dataclass(frozen=True)
class Block:
    page: str
    line: int
    language: str
    code: str

    def __str__(self) -> str:
        return f"{self.page}:{self.line}"


def blocks(language: str | None = None) -> list[Block]:
    """The fenced code blocks of every page (of ``language``), in order."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for match in _FENCE.finditer(text):
            indent = len(match.group(1))
            code = "\n".join(line[indent:] for line in match.group(3).splitlines())
            line = text.count("\n", 0, match.start()) + 1
            block = Block(page.relative_to(ROOT).as_posix(), line, match.group(2), code)
            if language is None or block.language == language:
                found.append(block)
    return found


def test_every_block_names_a_language_that_is_run_or_checked() -> None:
    assert len(blocks()) >= 30  # the pages were read
    assert [str(b) for b in blocks() if b.language not in LANGUAGES] == []


# ---- python: run as written -----------------------------------------------------------------

SOLVES = re.compile(r"\.solve\(")


def _python_params() -> list[object]:
    return [
        pytest.param(b, id=str(b), marks=[pytest.mark.slow] if SOLVES.search(b.code) else [])
        for b in blocks("python")
    ]


def test_the_python_examples_are_there() -> None:
    codes = [b.code for b in blocks("python")]
    readme = [b.code for b in blocks("python") if b.page == "README.md"]
    assert len(readme) == 1 and "build_planner(" in readme[0] and "replay_plan(" in readme[0]
    assert len(readme[0].splitlines()) <= 10  # the Python API in ten lines
    assert any("def propose(" in c and "StalmPlanner(" in c for c in codes)
    assert any("ProblemSpec(" in c and "RegionSpec(" in c and ".solve(" in c for c in codes)


@pytest.mark.parametrize("block", _python_params())
def test_a_python_block_runs_as_written(block: Block, capsys, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # anything it writes goes to a scratch folder
    namespace: dict[str, object] = {"__name__": "docs_example"}
    exec(compile(block.code, str(block), "exec"), namespace)
    printed = capsys.readouterr().out
    result = namespace.get("result")
    if isinstance(result, PlanResult):  # every example that solves prints the success first
        assert printed.startswith("True") and result.success, (str(block), printed)
        if "class ShortestFirst" in block.code:
            assert result.details.proposer == "shortest-first"


# ---- bash: commands that exist, with options they take ---------------------------------------


def _commands(code: str) -> list[list[str]]:
    """The simple commands of a bash block: continuation lines joined, comments dropped, split
    at ``&&``, ``;`` and ``|``, redirections and leading ``VAR=value`` assignments removed."""
    commands: list[list[str]] = []
    for line in code.replace("\\\n", " ").splitlines():
        words = shlex.split(line, comments=True)
        current: list[str] = []
        for word in [*words, "&&"]:
            if word in ("&&", ";", "|", "||"):
                if current:
                    commands.append(current)
                current = []
            elif word in (">", "<", "2>") and current:
                current.append("\0")  # the next word is a redirection target
            elif current and current[-1] == "\0":
                current.pop()
            elif not current and re.fullmatch(r"[A-Z_]+=.*", word):
                continue
            else:
                current.append(word)
    return commands


def _stalm_command(args: list[str]) -> None:
    """Parse ``stalm ARGS`` as Click would run it, down to the leaf command (nothing runs)."""
    command = typer.main.get_command(app)
    name: str | None = "stalm"
    parent = None
    while True:
        ctx = command.make_context(name, list(args), parent=parent)
        if not hasattr(command, "resolve_command"):  # a leaf command, its arguments parsed
            break
        rest = [*ctx._protected_args, *ctx.args]
        assert rest, f"stalm {' '.join(args)}: a group without a command"
        name, sub, args = command.resolve_command(ctx, rest)
        assert sub is not None and name is not None
        command, parent = sub, ctx


def _set_values(args: list[str]) -> list[str]:
    return [args[i + 1] for i, word in enumerate(args[:-1]) if word == "--set"]


def _bash_params() -> list[object]:
    return [pytest.param(b, id=str(b)) for b in blocks("bash")]


@pytest.mark.parametrize("block", _bash_params())
def test_a_bash_block_names_commands_that_exist(block: Block) -> None:
    commands = _commands(block.code)
    assert commands, str(block)
    for words in commands:
        program, args = words[0], words[1:]
        assert program in PROGRAMS, f"{block}: {program}"
        if program == "stalm":
            try:
                _stalm_command(args)
            except CLICK_EXCEPTION as error:
                pytest.fail(f"{block}: stalm {' '.join(args)}: {error.format_message()}")
            if _set_values(args):
                with_overrides(RunSettings(), _set_values(args))
        elif program in ("python", "python3") and args and not args[0].startswith("-"):
            assert (ROOT / args[0]).is_file(), f"{block}: {args[0]}"
        elif program == "mkdocs":
            assert args[0] in ("build", "serve"), f"{block}: mkdocs {args[0]}"


def test_the_bash_check_catches_an_unknown_option_and_setting() -> None:
    with pytest.raises(USAGE_ERROR, match="No such option"):
        _stalm_command(["solve", "P2", "--no-such-flag"])
    with pytest.raises(USAGE_ERROR, match="No such option"):
        _stalm_command(["bench", "ik", "--no-such-flag"])
    with pytest.raises(USAGE_ERROR, match="No such command"):
        _stalm_command(["no-such-command"])
    with pytest.raises(typer.BadParameter):
        _stalm_command(["solve", "P2", "--seed", "three"])
    from stalm.errors import StalmError

    with pytest.raises(StalmError):
        with_overrides(RunSettings(), ["search.no_such_key=1"])


def test_commands_are_split_as_bash_would() -> None:
    code = 'CMAKE_ARGS="-X" pip install -e ".[dev]"   # note\nstalm a --b c \\\n    --d e > f.yaml'
    assert _commands(code) == [
        ["pip", "install", "-e", ".[dev]"],
        ["stalm", "a", "--b", "c", "--d", "e"],
    ]
    assert _commands("python3 -m venv .venv && . .venv/bin/activate") == [
        ["python3", "-m", "venv", ".venv"],
        [".", ".venv/bin/activate"],
    ]


# ---- yaml: parses ------------------------------------------------------------------------------


@pytest.mark.parametrize("block", [pytest.param(b, id=str(b)) for b in blocks("yaml")])
def test_a_yaml_block_parses(block: Block) -> None:
    data = yaml.safe_load(block.code)
    if isinstance(data, dict) and "regions" in data:  # a problem file
        from stalm.api import Problem, check_problem_geometry, parse_problem

        check_problem_geometry(Problem(parse_problem(data, str(block)), str(block)))


def test_the_format_pages_problem_is_the_python_pages() -> None:
    """The YAML of the problems page and the ProblemSpec of the Python API page are one."""
    from stalm.api import parse_problem

    (file_block,) = [b for b in blocks("yaml") if b.page == "docs/problems.md"]
    (built,) = [b for b in blocks("python") if "ProblemSpec(" in b.code]
    namespace: dict[str, object] = {}
    exec(compile(built.code.split("problem = Problem(")[0], str(built), "exec"), namespace)
    assert parse_problem(yaml.safe_load(file_block.code)) == namespace["spec"]
