"""``stalm generate``: problems with a witness plan that replays, one or a suite of them."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console

from stalm.cli.display import shown
from stalm.cli.paths import check_output_file
from stalm.errors import StalmError
from stalm.generate.arrange import MAX_OBJECTS

if TYPE_CHECKING:
    from stalm.generate.clutter_meshes import ClutterMesh

commands = typer.Typer()
"""The top-level commands this module adds; :mod:`stalm.cli.main` composes them."""

console = Console(stderr=True)


def _sizes(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise StalmError(f"--sizes must be numbers separated by commas, got {text!r}") from None
    if not sizes or min(sizes) < 1:
        raise StalmError(f"--sizes must be positive numbers of objects, got {text!r}")
    return sizes


def _clutter(source: str | None, folder: Path) -> tuple[ClutterMesh, ...]:
    """The meshes ``--objects-from`` names, fitted and checked, said in one line."""
    from stalm.generate.clutter_meshes import clutter_from

    if source is None:
        return ()
    with console.status("checking meshes for clutter...") as status:
        made = clutter_from(source, folder, lambda message: status.update(shown(message)))
    console.print(shown(made.summary()), highlight=False, soft_wrap=True)
    return made.meshes


@commands.command("generate")
def generate_command(
    out: Annotated[
        Path,
        typer.Option(
            "-o",
            "--out",
            help="The problem file to write (its witness goes beside it), or with "
            "--suite the folder.",
        ),
    ],
    objects: Annotated[
        int,
        typer.Option(
            help="Movable objects (one problem): at most what the layout holds (kitchen-hall "
            "158, storeroom 346 with the default knobs; fewer with more goals or deeper "
            f"chains) and at most {MAX_OBJECTS}, and at least one per goal and occluder (with "
            "--trap one more; with 2 or more goals one reference object)."
        ),
    ] = 12,
    goals: Annotated[int, typer.Option(help="Goal objects (1-4).")] = 2,
    seed: Annotated[int, typer.Option(help="Seed: the same seed, the same file.")] = 0,
    occlusion_depth: Annotated[
        int, typer.Option(help="Occluders in front of each goal object (0-3).")
    ] = 1,
    door: Annotated[
        str, typer.Option(help="'closed' (the kitchen door must be opened) or 'open' (no door).")
    ] = "closed",
    trap: Annotated[
        bool,
        typer.Option(help="P5's trap: cans, then the grill, onto the walled counter (goals 2-3)."),
    ] = False,
    layout: Annotated[
        str,
        typer.Option(
            help="The static scene: a built-in layout (kitchen-hall, storeroom) or a layout "
            "file (a problem file with no objects and no goal, FILE.yaml)."
        ),
    ] = "kitchen-hall",
    objects_from: Annotated[
        str | None,
        typer.Option(
            metavar="DIR|pybullet_data",
            help="Make about half the clutter meshes: the OBJ files of a folder (each scaled to "
            "fill a slot, kept if it rests upright as loaded and comes back when tipped) or "
            "'pybullet_data', the set shipped with stalm; the kept count is said in one line.",
        ),
    ] = None,
    suite: Annotated[
        str | None, typer.Option(help="Make a suite of this name in the folder --out.")
    ] = None,
    sizes: Annotated[
        str,
        typer.Option(
            help=f"With --suite: object counts, comma-separated, each 1-{MAX_OBJECTS} and at "
            "most what the layout holds."
        ),
    ] = "8,16,32,64",
    per_size: Annotated[
        int, typer.Option(help="With --suite: problems per size (at least 1).")
    ] = 20,
    replace: Annotated[
        bool,
        typer.Option(
            "--replace",
            help="With --suite: replace the suite the folder holds (its files and index) "
            "whole; without it a folder holding another suite is refused.",
        ),
    ] = False,
) -> None:
    """Write a solvable problem (or a suite): a scene, objects behind chains of occluders, a
    goal, and a witness plan grounded and replayed in the simulator."""
    from stalm.generate.arrange import Knobs
    from stalm.generate.layout import load_layout
    from stalm.generate.problem_maker import generate_problem, problem_name
    from stalm.generate.suite import generate_suite, witness_path, write_generated
    from stalm.generate.suite_index import check_suite_name

    if door not in ("closed", "open"):
        raise StalmError(f"--door must be 'closed' or 'open', got {door!r}")
    if replace and suite is None:
        raise StalmError("--replace goes with --suite (one problem's files are always replaced)")
    static = load_layout(layout)
    if suite is not None:
        check_suite_name(suite)
        if out.exists() and not out.is_dir():
            raise StalmError(f"-o {out}: is a file; with --suite, -o names a folder")
        check_output_file(out / "index.json", "-o")
        counts = _sizes(sizes)
        knobs = Knobs(max(counts), goals, occlusion_depth, door == "closed", trap)
        for size in counts:  # before the meshes are scanned, which may take a minute
            static.check_capacity(dataclasses.replace(knobs, objects=size))
        knobs = dataclasses.replace(knobs, clutter=_clutter(objects_from, out))
        with console.status("generating the suite...") as status:
            made = generate_suite(
                suite,
                counts,
                per_size,
                seed,
                out,
                knobs,
                progress=lambda message: status.update(shown(message)),
                layout=static,
                replace=replace,
            )
        typer.echo(f"wrote {len(made.problems)} problems and {out / 'index.json'}")
        return
    if out.suffix not in (".yaml", ".yml"):
        raise StalmError(f"-o {out}: a problem file ends in .yaml")
    check_output_file(out, "-o")
    check_output_file(witness_path(out), "-o (its witness)")
    knobs = Knobs(objects, goals, occlusion_depth, door == "closed", trap)
    static.check_capacity(knobs)
    knobs = dataclasses.replace(knobs, clutter=_clutter(objects_from, out.parent))
    with console.status("generating (grounding the witness in the simulator)..."):
        generated = generate_problem(
            knobs,
            seed,
            problem_name(out.stem),
            layout=static,
            source=str(out),
            folder=out.parent,
        )
    witness = write_generated(generated, out)
    length = generated.problem.spec.optimal_length
    typer.echo(f"wrote {out} and {witness} (a {length}-action witness)")
