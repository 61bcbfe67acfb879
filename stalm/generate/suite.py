"""Suites of generated problems: many sizes, many seeds, one folder, an index.

``stalm generate --suite NAME --sizes 8,16,32,64 --per-size 20 --seed S -o DIR`` writes each
problem as ``DIR/NAME-NNN.yaml`` beside its witness ``DIR/NAME-NNN.witness.json`` and the
index ``DIR/index.json``: the suite's name, seed, sizes and knobs, and per problem its files
with the SHA-256 of each, its number of movable objects, its own seed and its witness's
length. ``stalm experiment scale --suite DIR`` reads the index and refuses a file whose hash
is not the index's (a problem edited after it was generated would be run and reported beside
the records of the one generated). Problem files are named relative to the folder, so a
suite copied or moved elsewhere still runs and replays. The name is an identifier, never a
path: every file is written inside the folder.

A problem's seed is drawn from the suite's seed and its index (``SeedSequence``), so a suite
made again with the same arguments is the same suite, file for file. The index is written
before the first problem and after each one, marked unfinished until the last: the same
command again resumes an interrupted suite, keeping each problem whose files still have their
recorded hashes. A folder holding another suite (other arguments, or files no index names) is
refused, unless asked to replace it whole (``replace``): one folder, one suite, one version.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stalm.errors import StalmError
from stalm.files import (
    MAX_PROBLEM_FILE_BYTES,
    MAX_RESULT_FILE_BYTES,
    read_json_file,
    write_together,
)
from stalm.generate.arrange import Knobs
from stalm.generate.layout import Layout, load_layout
from stalm.generate.problem_maker import Generated, generate_problem, problem_name
from stalm.generate.suite_index import (
    INDEX,
    SUITE_VERSION,
    Suite,
    SuiteProblem,
    check_suite_name,
    file_sha256,
    plain_name,
    read_index,
)
from stalm.trial.result import check_seed


def write_generated(generated: Generated, path: Path) -> Path:
    """Write a problem file and its witness (``NAME.witness.json``) beside it, both or neither
    (a witness that cannot be written leaves the old problem file as it was); the witness
    carries its problem, so it replays without the file."""
    witness = witness_path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_together([(path, generated.text), (witness, _witness_text(generated))])
    except OSError as error:
        raise StalmError(
            f"{path}: cannot write it and its witness {witness.name} "
            f"({error.strerror or error}); neither was written"
        ) from None
    return witness


def _witness_text(generated: Generated) -> str:
    return json.dumps(generated.witness_json(), indent=1) + "\n"


def witness_path(problem_file: Path) -> Path:
    return problem_file.with_name(problem_file.stem + ".witness.json")


def sha256_text(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class _Planned:
    """A problem the suite is to hold: its files' names, size and seed."""

    file: str
    objects: int
    seed: int

    @property
    def witness(self) -> str:
        return witness_path(Path(self.file)).name


def generate_suite(
    name: str,
    sizes: tuple[int, ...],
    per_size: int,
    seed: int,
    folder: Path,
    knobs: Knobs,
    progress: Callable[[str], None] = lambda _: None,
    layout: Layout | str = "kitchen-hall",
    *,
    replace: bool = False,
) -> Suite:
    """Generate and write a suite (see the module docstring); ``knobs.objects`` is replaced
    by each size. Everything that would stop it (the name, the layout, the sizes, the folder
    and its files, another suite there) is checked before the first problem is made."""
    if isinstance(layout, str):
        layout = load_layout(layout)
    check_suite_name(name)
    check_seed(seed, "--seed")  # SeedSequence takes no negative seed
    if not sizes or per_size < 1:
        raise StalmError("a suite needs --sizes and a --per-size of at least 1")
    for size in sizes:  # a size too small or too large fails here, before work
        layout.check_capacity(dataclasses.replace(knobs, objects=size))
    planned = [
        _Planned(
            f"{name}-{index:03d}.yaml",
            size,
            int(np.random.SeedSequence([seed, index]).generate_state(1)[0]),
        )
        for index, size in enumerate(s for s in sizes for _ in range(per_size))
    ]
    _check_folder(folder, planned)
    made = Suite(name, seed, _knobs_json(knobs), (), folder, tuple(sizes), per_size, layout.name)
    kept = _replace_old(folder) if replace else _resumable(folder, made, planned)
    folder.mkdir(parents=True, exist_ok=True)
    problems: list[SuiteProblem] = []
    _write_index(made, [kept[p.file] for p in planned if p.file in kept], complete=False)
    for index, plan in enumerate(planned):
        if plan.file in kept:
            problems.append(kept[plan.file])
            continue
        progress(f"{plan.file}: {plan.objects} objects ({index + 1} of {len(planned)})")
        path = folder / plan.file
        generated = generate_problem(
            dataclasses.replace(knobs, objects=plan.objects),
            plan.seed,
            problem_name(f"{name}_{index:03d}"),
            layout=layout,
            source=str(path),
            folder=folder,
        )
        write_generated(generated, path)
        problems.append(
            SuiteProblem(
                plan.file,
                plan.witness,
                plan.objects,
                plan.seed,
                int(generated.problem.spec.optimal_length or 0),
                sha256_text(generated.text),
                sha256_text(_witness_text(generated)),
            )
        )
        _write_index(made, problems, complete=False)
    _write_index(made, problems, complete=True)
    return dataclasses.replace(made, problems=tuple(problems))


def _check_folder(folder: Path, planned: list[_Planned]) -> None:
    """Refuse, before any work, a folder that is a file or lies under one, and a folder where
    one of the suite's files goes."""
    ancestor = folder
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise StalmError(f"-o {folder}: {ancestor} is a file, not a folder")
    for name in [INDEX, *(p.file for p in planned), *(p.witness for p in planned)]:
        if (folder / name).is_dir():
            raise StalmError(f"-o {folder}: {name} there is a folder; the suite writes a file")


def _arguments(suite: Suite) -> dict[str, Any]:
    """What makes a suite the suite it is: the same arguments, the same files."""
    return {
        "suite": suite.name,
        "seed": suite.seed,
        "sizes": list(suite.sizes),
        "per_size": suite.per_size,
        "layout": suite.layout,
        "knobs": suite.knobs,
    }


def _resumable(folder: Path, wanted: Suite, planned: list[_Planned]) -> dict[str, SuiteProblem]:
    """The problems already made of the suite ``wanted`` in ``folder`` (an interrupted run, or
    the whole suite), kept as they are; a StalmError when the folder holds anything else."""
    again = "add --replace to replace it whole, or give another -o"
    if not (folder / INDEX).exists():
        for plan in planned:
            for name in (plan.file, plan.witness):
                if (folder / name).exists():
                    raise StalmError(
                        f"-o {folder}: {name} is there and no suite index names it: {again}"
                    )
        return {}
    try:
        old = read_index(folder, complete=False)
    except StalmError as error:
        raise StalmError(f"{error}: {again}") from None
    if _arguments(old) != _arguments(wanted):
        differing = [k for k, v in _arguments(old).items() if _arguments(wanted)[k] != v]
        raise StalmError(
            f"-o {folder} holds another suite ({old.name!r}; its {', '.join(differing)} "
            f"differ): {again}"
        )
    kept = {}
    for problem in old.problems:
        files = [
            (problem.file, problem.sha256, MAX_PROBLEM_FILE_BYTES),
            (problem.witness, problem.witness_sha256, MAX_RESULT_FILE_BYTES),
        ]
        if not all((folder / name).exists() for name, _, _ in files):
            continue  # made again (the same arguments make the same files)
        for name, recorded, limit in files:
            if file_sha256(folder / name, limit) != recorded:
                raise StalmError(
                    f"{folder / name}: differs from the suite's index (edited after it was "
                    f"generated?): {again}"
                )
        kept[problem.file] = problem
    return kept


def _replace_old(folder: Path) -> dict[str, SuiteProblem]:
    """Remove the suite in ``folder`` (the files its index names, and the index); nothing is
    kept. Files no index names are left alone, but for those the new suite writes over."""
    index = folder / INDEX
    if not index.is_file():
        return {}
    try:
        data = read_json_file(index, "suite index")
        names = [
            plain_name(str(p.get(field)), index)
            for p in data["problems"]
            for field in ("file", "witness")
        ]
    except (StalmError, KeyError, TypeError, AttributeError):
        names = []  # unreadable: only the index goes; the new files replace the old names
    for name in names:
        if (folder / name).is_file():
            (folder / name).unlink()
    index.unlink()
    return {}


def _write_index(suite: Suite, problems: list[SuiteProblem], *, complete: bool) -> None:
    data = {
        "suite_version": SUITE_VERSION,
        **_arguments(suite),
        "complete": complete,
        "problems": [dataclasses.asdict(p) for p in problems],
    }
    write_together([(suite.folder / INDEX, json.dumps(data, indent=1) + "\n")])


def _knobs_json(knobs: Knobs) -> dict[str, Any]:
    data: dict[str, Any] = dataclasses.asdict(knobs)
    data.pop("objects")
    if knobs.clutter:
        data["clutter"] = [dataclasses.asdict(mesh) for mesh in knobs.clutter]  # as JSON reads
    else:
        data.pop("clutter")  # a suite of cans and bottles has the index it always had
    return data
