"""Fast Downward's cost against the number of objects: translate and search time of the
symbolic proposer's PDDL for P2's kitchen and hall (seven regions) holding 6, 12 and 24
objects.

The crowded problems keep P2's four objects and goal (the salter boxed in on counter2 behind
the closed door) and add cans in a grid on the six other regions, round robin, so the
relative placements a planner may ground grow with the objects beside each reference. Each
size is timed with relative placements grounded only for the goal's relations (the symbolic
proposer's default) and for every pair of objects (``goal_relations_only=False``), so the
benchmark shows what that restriction buys. The predicates of the initial state are computed
once per problem (untimed: ``stalm bench predicates`` times them) and fed to both.
"""

from __future__ import annotations

import copy
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from stalm.domain.mdp import Domain
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.pddl import domain_pddl, problem_pddl
from stalm.llm.problem_prompt import goal_literals
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.fast_downward import SEARCH, search_task, translate_task
from stalm.world.problem import Problem, load_problem

CAN_SPACING = 0.14
"""Metres between the centres of two added cans (radius 0.035: a gripper fits between)."""
KEEP_CLEAR = 0.12
"""Added cans stand at least this far from the problem's own objects."""


def crowded_problem_data(base: dict[str, Any], total_objects: int) -> dict[str, Any]:
    """``base`` (a problem file's data) with cans added up to ``total_objects`` objects, in
    a grid on every region that holds none of the goal's objects at the start."""
    data = copy.deepcopy(base)
    objects: list[dict[str, Any]] = data["objects"]
    goal_objects = {goal[0] for goal in data["goal"]}
    busy = {o["on"] for o in objects if o["name"] in goal_objects}
    spots: list[list[tuple[str, float, float]]] = []
    for region in data["regions"]:
        if region["name"] in busy:
            continue
        width, depth = region["usable"]
        taken = [o["at"] for o in objects if o["on"] == region["name"]]
        grid = []
        for i in range(int((width - 0.02) // CAN_SPACING)):
            for j in range(int((depth - 0.02) // CAN_SPACING)):
                x = -width / 2 + CAN_SPACING / 2 + 0.01 + i * CAN_SPACING
                y = -depth / 2 + CAN_SPACING / 2 + 0.01 + j * CAN_SPACING
                if all((x - a) ** 2 + (y - b) ** 2 >= KEEP_CLEAR**2 for a, b in taken):
                    grid.append((region["name"], round(x, 3), round(y, 3)))
        spots.append(grid)
    added = 0
    while len(objects) < total_objects:
        if not any(spots):
            raise ValueError(f"no room for {total_objects} objects on the free regions")
        for grid in spots:
            if grid and len(objects) < total_objects:
                region, x, y = grid.pop(0)
                added += 1
                objects.append(
                    {
                        "name": f"can{added}",
                        "shape": "cylinder",
                        "radius": 0.035,
                        "height": 0.2,
                        "on": region,
                        "at": [x, y],
                        "color": [0.6, 0.6, 0.65, 1],
                    }
                )
    data["name"] = f"{base['name']}_{total_objects}"
    data["description"] = f"{base['name']} with {total_objects} objects (bench symbolic)"
    data.pop("optimal_length", None)
    return data


def crowded_problem(base: str, total_objects: int, folder: Path) -> Problem:
    """The crowded version of problem ``base`` as a problem file in ``folder``, loaded."""
    data = yaml.safe_load(Path(load_problem(base).source).read_text(encoding="utf-8"))
    path = folder / f"{base.lower()}_{total_objects}.yaml"
    path.write_text(yaml.safe_dump(crowded_problem_data(data, total_objects)), encoding="utf-8")
    return load_problem(path)


def time_downward(
    problem: Problem,
    literals: frozenset[GroundLiteral],
    goal_relations_only: bool,
    plans: int = 3,
    seed: int = 0,
    time_limit_s: float = 120.0,
) -> dict[str, object]:
    """Translate once and search ``plans`` times (seeds ``seed``..), as the proposer does."""
    vocabulary = Vocabulary.from_problem(problem)
    with tempfile.TemporaryDirectory(prefix="stalm-bench-fd-") as folder:
        work = Path(folder)
        (work / "domain.pddl").write_text(
            domain_pddl(feedback=True, goal_relations_only=goal_relations_only)
        )
        (work / "problem.pddl").write_text(
            problem_pddl(
                vocabulary, sorted(literals), goal_literals(problem), "state", feedback=True
            )
        )
        start = time.perf_counter()
        try:
            translate_task(work, time_limit_s)
        except subprocess.TimeoutExpired:
            return {"translate_s": None, "why": f"translator over {time_limit_s:.0f} s"}
        translate_s = time.perf_counter() - start
        operators = (work / "task.sas").read_text().count("begin_operator")
        searches: list[float] = []
        lengths: list[int] = []
        for index in range(plans):
            start = time.perf_counter()
            try:
                run = search_task(work, SEARCH.format(seed=seed + index), time_limit_s)
            except subprocess.TimeoutExpired:
                searches.append(float("inf"))
                continue
            searches.append(time.perf_counter() - start)
            if run.plan is not None:
                lengths.append(sum(1 for line in run.plan.splitlines() if line.startswith("(")))
    return {
        "translate_s": translate_s,
        "operators": operators,
        "search_s": searches,
        "plan_lengths": lengths,
    }


def run(
    sizes: tuple[int, ...] = (6, 12, 24),
    base: str = "P2",
    report: Callable[[dict[str, object]], None] | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, object]]:
    say = progress or (lambda _message: None)
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory(prefix="stalm-bench-problems-") as folder:
        for size in sizes:
            problem = crowded_problem(base, size, Path(folder))
            say(f"{problem.name}: predicates of the initial state (untimed)")
            domain = Domain.create(problem)
            try:
                engine = PredicateEngine(problem, domain.sim, domain.base_planner)
                start = time.perf_counter()
                literals = engine.compute(problem.initial_state).literals
                predicates_s = time.perf_counter() - start
            finally:
                domain.close()
            for goal_only in (True, False):
                say(f"{problem.name}: Fast Downward, goal relations only: {goal_only}")
                row: dict[str, object] = {
                    "problem": problem.name,
                    "objects": len(problem.spec.objects),
                    "literals": len(literals),
                    "predicates_s": predicates_s,
                    "goal_relations_only": goal_only,
                    **time_downward(problem, literals, goal_only),
                }
                if report:
                    report(row)
                rows.append(row)
    return rows
