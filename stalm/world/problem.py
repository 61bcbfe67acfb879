"""A loaded problem: its validated spec, initial State and goal; and where problem files live.

Problems are found by name (``P5``, case-insensitive) in the directory named by the
``STALM_PROBLEMS_DIR`` environment variable, else the repository's ``problems/``; a path to a
YAML file is accepted anywhere a name is.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from stalm.errors import StalmError
from stalm.geometry.directions import Direction
from stalm.geometry.transforms import se2_to_world, wrap_angle
from stalm.world import robot as robot_model
from stalm.world.problem_file import load_problem_file
from stalm.world.spec import ProblemSpec
from stalm.world.state import ObjectPose, RobotConf, State

PROBLEM_HASH_FIELD = "problem_hash"
"""The field of result files and trial records that holds :attr:`Problem.content_hash`."""


@dataclass(frozen=True)
class GoalAtom:
    """One goal conjunct AtPosition(obj, direction, ref)."""

    obj: str
    direction: Direction
    ref: str

    def __str__(self) -> str:
        return f"AtPosition({self.obj}, {self.direction}, {self.ref})"


@dataclass(frozen=True)
class Problem:
    """A problem instance (O, R, D, s0, G, h) of the paper's §3.1."""

    spec: ProblemSpec
    source: str

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def horizon(self) -> int:
        return self.spec.horizon

    def state_mismatch(self, state: State) -> str | None:
        """Why ``state`` cannot be a State of this problem (other objects or doors), or None."""
        objects = {obj.name for obj in self.spec.objects}
        have = set(state.object_names)
        if have != objects:
            extra, missing = sorted(have - objects), sorted(objects - have)
            parts = [f"unknown objects {extra}"] if extra else []
            parts += [f"missing objects {missing}"] if missing else []
            return "; ".join(parts)
        doors = {door.name for door in self.spec.doors}
        unknown = sorted(set(state.open_doors) - doors)
        if unknown:
            return f"unknown doors {unknown}"
        return None

    @cached_property
    def content_hash(self) -> str:
        """A digest of the validated problem (not of its file: comments, layout and key order
        do not change it). Results record it so a replay can tell it has the same problem."""
        payload = json.dumps(self.spec.model_dump(mode="json"), sort_keys=True)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    @cached_property
    def goal(self) -> tuple[GoalAtom, ...]:
        return tuple(GoalAtom(g.obj, g.direction, g.ref) for g in self.spec.goal)

    @cached_property
    def initial_state(self) -> State:
        poses = []
        for obj in self.spec.objects:
            region = self.spec.region(obj.on)
            x, y = se2_to_world((*region.center, region.yaw), *obj.at)
            poses.append(
                (obj.name, ObjectPose.make(x, y, region.top, wrap_angle(region.yaw + obj.yaw)))
            )
        return State(
            poses=tuple(sorted(poses)),
            open_doors=frozenset(),
            robot=RobotConf.make(
                self.spec.robot.base, robot_model.CARRY_LIFT, robot_model.CARRY_ARM
            ),
        )


def problems_dir() -> Path:
    """Where named problems are looked up."""
    env = os.environ.get("STALM_PROBLEMS_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "problems"


def available_problems() -> list[Path]:
    return sorted(path for path in problems_dir().glob("*.yaml") if not path.name.startswith("_"))


def load_problem(name_or_path: str | Path) -> Problem:
    """Load a problem by name (``P5``) or by the path of a YAML file."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return Problem(load_problem_file(path), str(path))
    wanted = str(name_or_path).lower()
    for candidate in available_problems():
        if candidate.stem.lower() == wanted:
            return Problem(load_problem_file(candidate), str(candidate))
    names = ", ".join(c.stem.upper() for c in available_problems()) or "none"
    raise StalmError(
        f"unknown problem '{name_or_path}': no file {wanted}.yaml in {problems_dir()} "
        f"(available: {names})"
    )
