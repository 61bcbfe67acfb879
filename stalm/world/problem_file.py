"""Reading a problem file (YAML) into a validated :class:`~stalm.world.spec.ProblemSpec`.

The file's side of loading: reading its text, refusing what is no problem file before it is
validated (not a regular file, too long, not UTF-8, not YAML, an alias bomb: the guards of
:mod:`stalm.files`, which settings files share), and turning pydantic's validation errors into
one :class:`~stalm.errors.StalmError` naming the file and the field path
(``problems/p5.yaml: objects[2].radius: must be greater than 0``). A problem path can come
from a result or record someone sent, so an error never quotes the file beyond a short
escaped excerpt: a file that has none of a problem's fields (``/etc/passwd`` named as a
problem) is "not a problem file", and field names are cut short. Kept apart from the spec
models (:mod:`stalm.world.spec`), which say what a valid problem is and know nothing of files.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import ValidationError

from stalm.errors import StalmError
from stalm.files import MAX_PROBLEM_FILE_BYTES, excerpt, load_yaml, read_text
from stalm.world.object_spec import MESH_BASE_CONTEXT
from stalm.world.spec import ProblemSpec

MAX_ERROR_LINES = 6
"""Validation problems listed at most (a file with hundreds of them is not the user's typo)."""
_FIELD_CHARS = 40
"""Characters of one field name quoted in an error."""
REQUIRED_FIELDS = ("name", "regions", "objects", "robot", "goal")


def format_validation_error(path: str, error: ValidationError) -> str:
    """Pydantic's errors as lines ``path: field.path: message`` (at most
    :data:`MAX_ERROR_LINES`); robot files share it, so their errors read the same."""
    items = error.errors()
    lines = []
    for item in items[:MAX_ERROR_LINES]:
        location = _format_location(item.get("loc", ()))
        message = str(item.get("msg", "invalid")).removeprefix("Value error, ")
        lines.append(f"{path}: {location}: {message}" if location else f"{path}: {message}")
    if len(items) > MAX_ERROR_LINES:
        lines.append(f"{path}: ... and {len(items) - MAX_ERROR_LINES} more")
    return "\n".join(lines)


def _format_location(loc: tuple[object, ...]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            name = str(part)
            if len(name) > _FIELD_CHARS or not name.isprintable():
                name = excerpt(name, _FIELD_CHARS)
            text += f".{name}" if text else name
    return text


def _first_boolean(data: object, loc: tuple[object, ...] = ()) -> str | None:
    """Where the first boolean of problem data is and what to write instead, or None.

    No field of a problem file is a boolean, but YAML 1.1 reads a bare ``on``, ``off``,
    ``yes`` and ``no`` as one: ``on: table3`` is the key ``true``, ``[salter, on, table2]``
    holds ``true``. Pydantic would report the mapping key as "Keys should be strings" beside
    a missing ``on`` for every object; this says it once, in one line, with the fix."""
    found: list[str] = []

    def visit(value: object, at: tuple[object, ...]) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                if isinstance(key, bool):
                    named = key and isinstance(item, str)
                    quoted = f"'on': {item:.{_FIELD_CHARS}}" if named else "'on'"
                    found.append(
                        f"{_format_location(at) or 'the file'}: a key reads as {str(key).lower()}"
                        f": YAML reads a bare on, off, yes or no as a boolean; quote it "
                        f"({quoted})"
                    )
                visit(item, (*at, key))
        elif isinstance(value, list):
            for index, item in enumerate(value):
                visit(item, (*at, index))
        elif isinstance(value, bool):
            found.append(
                f"{_format_location(at)}: {str(value).lower()} is how YAML reads a bare on, off, "
                "yes or no; quote it ('on')"
            )

    visit(data, loc)
    if not found:
        return None
    more = f" (and {len(found) - 1} more)" if len(found) > 1 else ""
    return found[0] + more


def parse_problem(
    data: object,
    source: str = "<problem>",
    spec: type[ProblemSpec] = ProblemSpec,
    base: Path | None = None,
) -> ProblemSpec:
    """Validate already-loaded problem data; errors name ``source`` and the field. ``spec``
    may be a narrower or looser kind of problem (a generator's layout: one without objects)
    validated by the same rules and reported the same way. A mesh object's relative file path
    resolves against ``base`` (the problem file's folder; the working folder if None)."""
    if not isinstance(data, dict):
        kind = "text" if isinstance(data, str) else type(data).__name__
        raise StalmError(f"{source}: a problem file must be a mapping of fields, got {kind}")
    if not any(name in data for name in REQUIRED_FIELDS):
        # quoting any of it could print a file read by mistake (a record's "/etc/shadow")
        raise StalmError(
            f"{source}: not a problem file (it has none of the fields {', '.join(REQUIRED_FIELDS)})"
        )
    boolean = _first_boolean(data)
    if boolean is not None:
        raise StalmError(f"{source}: {boolean}")
    try:
        return spec.model_validate(data, context={MESH_BASE_CONTEXT: base})
    except ValidationError as error:
        raise StalmError(format_validation_error(source, error)) from None


def load_problem_file(path: Path) -> ProblemSpec:
    """Read and validate one problem file (a regular file of at most
    :data:`~stalm.files.MAX_PROBLEM_FILE_BYTES`)."""
    text = read_text(path, MAX_PROBLEM_FILE_BYTES, "problem file")
    data = load_yaml(text, str(path))
    return parse_problem(data, str(path), base=path.parent)
