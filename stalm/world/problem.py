"""A loaded problem: its validated spec, initial State and goal; and where problem files live.

Problems are found by name (``P5``, case-insensitive): first in the folders the
``STALM_PROBLEMS_DIR`` environment variable names (one, or several separated by ``os.pathsep``),
then among the problems shipped inside the package (``stalm/problems/``, package data, so they
are found after any install, from any folder). A file there adds a problem, or overrides a
shipped one of the same name. A path to a YAML file is accepted anywhere a name is.
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
from stalm.world.problem_file import load_problem_file, parse_problem
from stalm.world.robot_description import Robot
from stalm.world.robot_loader import builtin_robots, robot_named
from stalm.world.robot_stance import fixed_base_mismatch
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
        joints = len(self.robot.arm_joints)
        if len(state.robot.arm) != joints:
            return f"robot.arm has {len(state.robot.arm)} joints; {self.robot.name}'s has {joints}"
        return None

    @cached_property
    def content_hash(self) -> str:
        """A digest of the validated problem (not of its file: comments, layout and key order
        do not change it) and, when it names a robot file, of that file and the URDF's shapes.
        Results record it so a replay can tell it has the same problem."""
        data = self.spec.model_dump(mode="json")
        if self.spec.robot.file is not None:  # what the robot is, not only where its file was
            robot = self.robot
            robot_file = hashlib.sha256(Path(robot.source).read_bytes()).hexdigest()
            data["robot_content"] = [robot_file, robot.urdf_sha256]
        payload = json.dumps(data, sort_keys=True)
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
        carry = self.robot.carry_conf
        return State(
            poses=tuple(sorted(poses)),
            open_doors=frozenset(),
            robot=RobotConf.make(self.spec.robot.base, carry[0], carry[1:]),
        )

    @cached_property
    def robot(self) -> Robot:
        """The robot the problem names (the Panda unless its ``robot.file`` says another)."""
        return robot_named(self.spec.robot.robot)

    def with_robot(self, robot: str) -> Problem:
        """This problem for another robot (``--robot``): a built-in robot's name, or a robot
        file's path (relative to the working folder), which the problem then names by its
        absolute path; the problem's own relative paths (a mesh) keep their folder. A
        StalmError if the robot cannot be loaded, has no gripper, or is not on a mobile base."""
        path = Path(robot).expanduser()
        named = robot in builtin_robots() or (path.suffix == "" and len(path.parts) == 1)
        file = robot if named else str(path.resolve())  # a bare word: a (maybe unknown) name
        data = self.spec.model_dump(mode="json")
        data["robot"]["file"] = file
        source = f"{self.source} with --robot {robot}"
        problem = Problem(parse_problem(data, source, base=self.spec.files_folder), self.source)
        _ = problem.robot.gripper  # what planning needs: errors now, not later
        why = fixed_base_mismatch(problem.spec, problem.robot)
        if why is not None:
            raise StalmError(why)
        return problem


PROBLEMS_ENV = "STALM_PROBLEMS_DIR"
"""The environment variable naming folders of problem files searched before the shipped ones."""


def shipped_problems_dir() -> Path:
    """The folder of problem files inside the package: P1..P6 and ``layouts/``."""
    return Path(__file__).resolve().parent.parent / "problems"


def problems_dirs() -> tuple[Path, ...]:
    """Where named problems are looked up, the first folder holding a name winning:
    ``$STALM_PROBLEMS_DIR``'s folders, then :func:`shipped_problems_dir`. A StalmError names a
    folder of ``$STALM_PROBLEMS_DIR`` that is not one."""
    env = os.environ.get(PROBLEMS_ENV, "")
    extra = [Path(part) for part in env.split(os.pathsep) if part.strip()]
    for folder in extra:
        if not folder.is_dir():
            raise StalmError(f"${PROBLEMS_ENV}: {folder} is not a folder")
    return (*extra, shipped_problems_dir())


def available_problems() -> list[Path]:
    """The problem files found by name, one per name (case-insensitive), sorted by name; a
    file whose name starts with ``_`` is none."""
    found: dict[str, Path] = {}
    for folder in problems_dirs():
        for path in sorted(folder.glob("*.yaml")):
            if not path.name.startswith("_"):
                found.setdefault(path.stem.lower(), path)
    return [found[name] for name in sorted(found)]


def _folders_text() -> str:
    return " or ".join(str(folder) for folder in problems_dirs())


def no_problems_error() -> StalmError:
    """What to say when no problem file is found by name at all (a broken install)."""
    return StalmError(
        f"no problem files in {_folders_text()}: the package's own (stalm/problems) are missing, "
        f"so reinstall stalm, or name a folder of problem files in ${PROBLEMS_ENV}"
    )


def _with_its_robot(problem: Problem) -> Problem:
    """``problem`` once the robot its ``robot.file`` names has loaded: a StalmError naming the
    problem file and the field if it does not (before any scene is built)."""
    if problem.spec.robot.file is not None:
        try:
            _ = problem.robot
        except StalmError as error:
            raise StalmError(f"{problem.source}: robot.file: {error}") from None
    return problem


def load_problem(name_or_path: str | Path) -> Problem:
    """Load a problem by name (``P5``) or by the path of a YAML file."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return _with_its_robot(Problem(load_problem_file(path), str(path)))
    wanted = str(name_or_path).lower()
    for candidate in available_problems():
        if candidate.stem.lower() == wanted:
            return _with_its_robot(Problem(load_problem_file(candidate), str(candidate)))
    names = ", ".join(c.stem.upper() for c in available_problems()) or "none"
    raise StalmError(
        f"unknown problem '{name_or_path}': no file {wanted}.yaml in {_folders_text()} "
        f"(available: {names})"
    )
