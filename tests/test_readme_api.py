"""The README's Python API examples run as written."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from stalm.api import PlanResult

README = Path(__file__).resolve().parents[1] / "README.md"


def api_examples() -> list[str]:
    """The Python code blocks of the README's "Python API" section, in order."""
    text = README.read_text(encoding="utf-8")
    section = text.split("\n## Python API\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.DOTALL)


def test_the_readme_has_the_two_api_examples() -> None:
    examples = api_examples()
    assert len(examples) == 2
    assert "build_planner(" in examples[0] and "replay_plan(" in examples[0]
    assert "def propose(" in examples[1] and "StalmPlanner(" in examples[1]


@pytest.mark.slow
@pytest.mark.parametrize("index", [0, 1])
def test_the_readmes_api_example_runs_as_written(index: int, capsys) -> None:
    namespace: dict[str, object] = {"__name__": "readme_example"}
    exec(
        compile(api_examples()[index], f"README.md Python API example {index + 1}", "exec"),
        namespace,
    )
    printed = capsys.readouterr().out
    assert printed.startswith("True"), printed  # both solve P2 and print the success first
    result = namespace["result"]
    assert isinstance(result, PlanResult) and result.success
    if index == 1:
        assert result.details["proposer"] == "shortest-first"
