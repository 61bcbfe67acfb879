"""Reading a problem file (YAML) into a validated :class:`~stalm.world.spec.ProblemSpec`.

The file's side of loading: reading its text, refusing what is no problem file before it is
validated (not UTF-8, too long, not YAML, an alias bomb), and turning pydantic's validation
errors into one :class:`~stalm.errors.StalmError` naming the file and the field path
(``problems/p5.yaml: objects[2].radius: must be greater than 0``). Kept apart from the spec
models (:mod:`stalm.world.spec`), which say what a valid problem is and know nothing of files.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import ValidationError

from stalm.errors import StalmError
from stalm.world.spec import ProblemSpec


def _format_validation_error(path: str, error: ValidationError) -> str:
    lines = []
    for item in error.errors():
        location = _format_location(item.get("loc", ()))
        message = str(item.get("msg", "invalid")).removeprefix("Value error, ")
        lines.append(f"{path}: {location}: {message}" if location else f"{path}: {message}")
    return "\n".join(lines)


def _format_location(loc: tuple[object, ...]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
    return text


def parse_problem(data: object, source: str = "<problem>") -> ProblemSpec:
    """Validate already-loaded problem data; errors name ``source`` and the field."""
    if not isinstance(data, dict):
        raise StalmError(f"{source}: a problem file must be a mapping of fields, got {data!r:.60}")
    try:
        return ProblemSpec.model_validate(data)
    except ValidationError as error:
        raise StalmError(_format_validation_error(source, error)) from None


def load_problem_file(path: Path) -> ProblemSpec:
    """Read and validate one problem file."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as error:
        raise StalmError(f"{path}: cannot read problem file ({error.strerror})") from None
    except UnicodeDecodeError as error:
        raise StalmError(
            f"{path}: not a problem file (not UTF-8 text: byte {error.object[error.start]:#04x} "
            f"at offset {error.start})"
        ) from None
    if len(text) > MAX_PROBLEM_FILE_CHARS:
        raise StalmError(
            f"{path}: a problem file of {len(text)} characters is too long "
            f"(at most {MAX_PROBLEM_FILE_CHARS})"
        )
    try:
        data = yaml.load(text, Loader=_LOADER)  # a safe loader (libyaml's when available)
    except yaml.YAMLError as error:
        raise StalmError(f"{path}: not valid YAML: {error}") from None
    except (ValueError, OverflowError, RecursionError) as error:  # e.g. date 2001-02-30
        raise StalmError(f"{path}: not valid YAML: {type(error).__name__}: {error}") from None
    problem = _shared_or_huge(data)
    if problem is not None:
        raise StalmError(f"{path}: {problem}")
    return parse_problem(data, str(path))


MAX_PROBLEM_FILE_CHARS = 1_000_000
"""The six problems are 3 to 6 kB; a file a thousand times larger is not a problem file."""


_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""libyaml's safe loader is fast and limits nesting; the pure-Python one recurses for seconds."""
MAX_PROBLEM_NODES = 100_000


def _shared_or_huge(data: object) -> str | None:
    """Why loaded YAML is no problem file: too many values once aliases are expanded (a few
    lines of nested ``*name`` aliases stand for billions of values, or a cycle for infinitely
    many, and would validate for hours). The six problems hold about a thousand."""
    stack = [data]
    count = 0
    while stack:
        node = stack.pop()
        count += 1
        if count > MAX_PROBLEM_NODES:
            return f"more than {MAX_PROBLEM_NODES} values (aliases expanded): not a problem file"
        if isinstance(node, dict):
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
    return None
