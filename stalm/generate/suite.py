"""Suites of generated problems: many sizes, many seeds, one folder, an index.

``stalm generate --suite NAME --sizes 8,16,32,64 --per-size 20 --seed S -o DIR`` writes each
problem as ``DIR/NAME-NNN.yaml`` beside its witness ``DIR/NAME-NNN.witness.json`` and the
index ``DIR/index.json``: the suite's name, seed and knobs, and per problem its files, its
number of movable objects, its own seed and its witness's length. ``stalm experiment scale
--suite DIR`` reads the index. Problem files are named relative to the folder, so a suite
copied or moved elsewhere still runs and replays.

A problem's seed is drawn from the suite's seed and its index (``SeedSequence``), so a suite
made again with the same arguments is the same suite, file for file.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stalm.errors import StalmError
from stalm.generate.arrange import Knobs
from stalm.generate.problem_maker import Generated, generate_problem, problem_name

INDEX = "index.json"
SUITE_VERSION = 1


@dataclass(frozen=True)
class SuiteProblem:
    """One problem of a suite, as its index names it."""

    file: str
    witness: str
    objects: int
    seed: int
    optimal_length: int


@dataclass(frozen=True)
class Suite:
    """A suite's index (see the module docstring); ``folder`` is where it was read from."""

    name: str
    seed: int
    knobs: dict[str, Any]
    problems: tuple[SuiteProblem, ...]
    folder: Path

    def path(self, problem: SuiteProblem) -> Path:
        return self.folder / problem.file


def write_generated(generated: Generated, path: Path) -> Path:
    """Write a problem file and its witness (``NAME.witness.json``) beside it; the witness
    carries its problem, so it replays without the file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    witness = witness_path(path)
    _write_atomically(path, generated.text)
    _write_atomically(witness, json.dumps(generated.witness_json(), indent=1) + "\n")
    return witness


def witness_path(problem_file: Path) -> Path:
    return problem_file.with_name(problem_file.stem + ".witness.json")


def _write_atomically(path: Path, text: str) -> None:
    temporary = path.with_name(path.name + ".part")
    temporary.write_text(text, encoding="utf-8")
    temporary.replace(path)


def generate_suite(
    name: str,
    sizes: tuple[int, ...],
    per_size: int,
    seed: int,
    folder: Path,
    knobs: Knobs,
    progress: Callable[[str], None] = lambda _: None,
    layout: str = "kitchen-hall",
) -> Suite:
    """Generate and write a suite (see the module docstring); ``knobs.objects`` is replaced
    by each size. A problem already written with its witness (a suite interrupted and made
    again) is kept, so making a suite resumes where it stopped."""
    if not sizes or per_size < 1:
        raise StalmError("a suite needs --sizes and a --per-size of at least 1")
    for size in sizes:
        dataclasses.replace(knobs, objects=size)  # a size too small fails here, before work
    folder.mkdir(parents=True, exist_ok=True)
    problems: list[SuiteProblem] = []
    total = len(sizes) * per_size
    for size in sizes:
        for _ in range(per_size):
            index = len(problems)
            file = f"{name}-{index:03d}.yaml"
            own_seed = int(np.random.SeedSequence([seed, index]).generate_state(1)[0])
            path = folder / file
            generated = None
            if not (path.exists() and witness_path(path).exists()):
                progress(f"{file}: {size} objects ({index + 1} of {total})")
                generated = generate_problem(
                    dataclasses.replace(knobs, objects=size),
                    own_seed,
                    problem_name(f"{name}_{index:03d}"),
                    layout=layout,
                    source=str(path),
                )
                write_generated(generated, path)
                length = generated.problem.spec.optimal_length or 0
            else:
                length = _optimal_length(path)
            problems.append(
                SuiteProblem(file, witness_path(path).name, size, own_seed, int(length))
            )
    suite = Suite(name, seed, _knobs_json(knobs), tuple(problems), folder)
    _write_atomically(folder / INDEX, json.dumps(_index_json(suite), indent=1) + "\n")
    return suite


def _optimal_length(path: Path) -> int:
    from stalm.world.problem import load_problem

    return load_problem(path).spec.optimal_length or 0


def _knobs_json(knobs: Knobs) -> dict[str, Any]:
    data: dict[str, Any] = dataclasses.asdict(knobs)
    data.pop("objects")
    return data


def _index_json(suite: Suite) -> dict[str, Any]:
    return {
        "suite_version": SUITE_VERSION,
        "suite": suite.name,
        "seed": suite.seed,
        "knobs": suite.knobs,
        "problems": [dataclasses.asdict(p) for p in suite.problems],
    }


def read_suite(folder: Path) -> Suite:
    """The suite whose index is in ``folder`` (a StalmError naming what is wrong)."""
    index = folder / INDEX
    try:
        data = json.loads(index.read_text(encoding="utf-8"))
    except OSError as error:
        raise StalmError(f"{index}: cannot read the suite's index ({error.strerror})") from None
    except ValueError as error:
        raise StalmError(f"{index}: not a suite index ({error})") from None
    try:
        problems = tuple(
            SuiteProblem(
                file=_plain_name(str(p["file"]), index),
                witness=_plain_name(str(p["witness"]), index),
                objects=int(p["objects"]),
                seed=int(p["seed"]),
                optimal_length=int(p["optimal_length"]),
            )
            for p in data["problems"]
        )
        return Suite(str(data["suite"]), int(data["seed"]), dict(data["knobs"]), problems, folder)
    except (KeyError, TypeError, ValueError) as error:
        raise StalmError(f"{index}: not a suite index (field {error})") from None


def _plain_name(name: str, index: Path) -> str:
    """A file of the suite's own folder: a name, never a path elsewhere."""
    if Path(name).name != name or name in ("", ".", ".."):
        raise StalmError(f"{index}: {name!r} is not a file name in the suite's folder")
    return name
