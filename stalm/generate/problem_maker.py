"""One generated problem: its file, checked in the simulator, with a witness that replays.

:func:`generate_problem` draws a scene (:mod:`stalm.generate.layout`) and an arrangement
(:mod:`stalm.generate.arrange`) from ``seed``, writes them as problem-file data with every
coordinate rounded to :data:`DECIMALS` places (0.1 mm, so that another machine's last bits do
not show in the file), loads that data as ``stalm`` loads any problem, checks the scene as
``stalm problems --file`` does (with mesh clutter, settling it under gravity too), and grounds
the construction's plan
(:mod:`stalm.generate.witness`). A candidate that fails any of these is dropped and the next
is drawn (``numpy.random.default_rng([seed, candidate])``), at most :data:`CANDIDATES` of them.
The witness's length is the problem's ``optimal_length`` (an upper bound).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from stalm.errors import StalmError
from stalm.generate.arrange import Arrangement, Knobs, arrange
from stalm.generate.clutter_meshes import scale_places
from stalm.generate.layout import Layout, load_layout, scene
from stalm.generate.witness import NoWitness, Witness, ground_witness
from stalm.json_object import JsonObject
from stalm.motion.problem_check import problem_geometry_faults
from stalm.trial.details import RunDetails
from stalm.trial.result import Counters, PhaseTimes, PlanResult
from stalm.world.physics_check import unsettled_objects
from stalm.world.problem import Problem
from stalm.world.problem_file import parse_problem
from stalm.world.problem_record import problem_fields

DECIMALS = 4
"""Places every coordinate of a generated file is rounded to: 0.1 mm (a mesh's scale keeps at
least 4 significant digits: :func:`~stalm.generate.clutter_meshes.scale_places`)."""
CANDIDATES = 25
"""Candidates drawn for one seed before giving up."""
TIME_BUDGET_S = 600.0
"""A generated problem's budget: the paper's larger one."""
HORIZON = 20
"""The paper's horizon; a problem whose witness is longer gets the witness's length and
:data:`HORIZON_SLACK` more."""
HORIZON_SLACK = 6
NAME = re.compile(r"[^A-Za-z0-9_]")


@dataclass(frozen=True)
class WitnessDetails:
    """A witness's record in its result file: its task plan and the candidate arrangement
    it was found for (no replay check is recorded: generation already replayed it)."""

    witness: Witness
    candidate: int

    @property
    def proposer(self) -> None:
        return None

    def to_json(self) -> JsonObject:
        task_plan = [str(step) for step in self.witness.plan]
        return {"witness": {"task_plan": task_plan, "candidate": self.candidate}}


@dataclass(frozen=True)
class Generated:
    """A generated problem, its file's text, and its witness."""

    problem: Problem
    text: str
    witness: Witness
    candidate: int

    def witness_json(self) -> dict[str, Any]:
        """The witness as a result file (``stalm replay`` reads it) carrying its problem, named
        as a solve's result names it (the problem's ``name``)."""
        result = PlanResult(
            problem=self.problem.name,
            planner="witness",
            seed=0,
            success=True,
            plan=self.witness.actions,
            states=self.witness.states,
            times=PhaseTimes(),
            counters=Counters(),
            termination="goal",
            details=RunDetails(WitnessDetails(self.witness, self.candidate)),
        )
        return {**result.to_json(), **problem_fields(self.problem)}


def problem_name(text: str) -> str:
    """An identifier for a problem from a file name (letters, digits and ``_``)."""
    name = NAME.sub("_", text)
    return name if name[:1].isalpha() else f"g_{name}"


def generate_problem(
    knobs: Knobs,
    seed: int,
    name: str,
    *,
    layout: Layout | str = "kitchen-hall",
    source: str = "<generated>",
    folder: Path | None = None,
) -> Generated:
    """The first candidate for ``seed`` that passes every check (see the module docstring);
    ``layout`` is a :class:`Layout` or what ``--layout`` names; ``folder`` is where the file
    goes, which clutter meshes named by a relative path are relative to."""
    if seed < 0:
        raise StalmError(f"--seed must be at least 0, got {seed}")
    if isinstance(layout, str):
        layout = load_layout(layout)
    layout.check_capacity(knobs)
    reasons: list[str] = []
    for candidate in range(CANDIDATES):
        rng = np.random.default_rng([seed, candidate])
        data, arrangement = _problem_data(knobs, seed, name, layout, rng)
        problem = Problem(parse_problem(data, source, base=folder), source)
        faults = problem_geometry_faults(problem) or _unsettled(problem, knobs)
        if faults:
            reasons.append(faults[0])
            continue
        witness = ground_witness(problem, arrangement.plan, arrangement.dumps, rng)
        if isinstance(witness, NoWitness):
            reasons.append(witness.reason)
            continue
        data["optimal_length"] = len(witness.actions)
        data["horizon"] = max(HORIZON, len(witness.actions) + HORIZON_SLACK)
        final = Problem(parse_problem(data, source, base=folder), source)
        return Generated(final, _yaml_text(data), witness, candidate)
    raise StalmError(
        f"no problem for seed {seed} after {CANDIDATES} candidates; the last failed: "
        f"{reasons[-1] if reasons else 'unknown'}"
    )


def _unsettled(problem: Problem, knobs: Knobs) -> list[str]:
    """With mesh clutter, the objects that do not rest where the file puts them, in words (a
    mesh kept for resting alone could still be knocked by a neighbour's fall); cans and
    bottles always rest, so a scene of them is not settled, and is made as before."""
    if not knobs.clutter:
        return []
    return [
        f"{drift.obj} does not rest where it stands (moved {drift.displacement_m * 1000:.1f} "
        f"mm, tilted {drift.tilt_deg:.1f} deg)"
        for drift in unsettled_objects(problem)
    ]


def _problem_data(
    knobs: Knobs, seed: int, name: str, layout: Layout, rng: np.random.Generator
) -> tuple[dict[str, Any], Arrangement]:
    """The problem file's fields (rounded) and the arrangement they come from."""
    static = scene(layout, rng, door=knobs.door, trap=knobs.trap)
    door = static["doors"][0]["name"] if static["doors"] else None
    arrangement = arrange(
        static["regions"],
        knobs,
        rng,
        door,
        layout.walled,
        layout.grill_start,
        clear_fronts=layout.clear_fronts,
    )
    depth = knobs.occlusion_depth
    description = (
        f"Generated by stalm generate (layout {layout.name}, seed {seed}): {knobs.objects} "
        f"objects, {knobs.goals} goal objects behind {depth} "
        f"occluder{'s' if depth != 1 else ''} each"
        + (", the door closed" if door else ", no door")
        + (", the grill trap of P5" if knobs.trap else "")
        + "."
    )
    data: dict[str, Any] = {
        "name": name,
        "description": description,
        "horizon": HORIZON,
        "time_budget_s": TIME_BUDGET_S,
        **static,
        "objects": arrangement.objects,
        "goal": arrangement.goal,
    }
    return _rounded(data), arrangement


def _rounded(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, DECIMALS) + 0.0  # + 0.0: no -0.0 in the file
    if isinstance(value, dict):
        return {
            k: round(v, scale_places(v)) if k == "scale" else _rounded(v) for k, v in value.items()
        }
    if isinstance(value, list | tuple):
        return [_rounded(v) for v in value]
    return value


class _Dumper(yaml.SafeDumper):
    """Vectors in flow style (``[-4.6, 3.2]``), as the hand-written problem files have them."""


def _list(dumper: yaml.SafeDumper, value: list[Any]) -> yaml.Node:
    flow = all(not isinstance(v, dict | list) for v in value)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", value, flow_style=flow)


_Dumper.add_representer(list, _list)


def _yaml_text(data: dict[str, Any]) -> str:
    header = f"# {data['name']}: {data['description']}\n"
    return header + yaml.dump(data, Dumper=_Dumper, sort_keys=False, width=100)
