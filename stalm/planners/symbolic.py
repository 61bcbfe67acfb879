"""A symbolic task-plan proposer: Fast Downward on the predicate PDDL of the current state.

It stands in for the language model's batch (``stalm solve --proposer symbolic``): the strict
PDDL of :mod:`stalm.llm.pddl` with the state's geometric predicates as init is translated by
Fast Downward's translator and searched by its planner (the binary shipped in the PyPI package
``up-fast-downward``). Diversity comes from greedy search with randomised successor order, one
seed per plan; duplicates are dropped. Like a model, it knows only the predicates, not the
shapes: it has no way to tell that P5's grill must go last, which the tree search then fixes.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from stalm.domain.actions import DiscreteAction
from stalm.domain.serialize import discrete_from_json
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.pddl import domain_pddl, problem_pddl
from stalm.llm.problem_prompt import goal_literals
from stalm.planners.proposers import Proposal
from stalm.predicates.literals import GroundLiteral
from stalm.world.problem import Problem
from stalm.world.state import State

SEARCH = "lazy_greedy([ff()], preferred=[ff()], randomize_successors=true, random_seed={seed})"


def downward_binary() -> Path:
    """The Fast Downward search binary from ``up-fast-downward`` (found without importing the
    package, which would pull in the Unified Planning framework)."""
    spec = importlib.util.find_spec("up_fast_downward")
    if spec is None or not spec.submodule_search_locations:
        raise StalmError("the symbolic proposer needs the package 'up-fast-downward'")
    root = Path(next(iter(spec.submodule_search_locations)))
    binary = root / "downward" / "builds" / "release" / "bin" / "downward"
    if not binary.exists():
        raise StalmError(f"Fast Downward's search binary is missing: {binary}")
    return binary


def _read_plan(text: str, vocabulary: Vocabulary) -> tuple[DiscreteAction, ...]:
    """Fast Downward's plan file: one ``(op arg ...)`` per line, ``;`` comments."""
    del vocabulary
    actions = []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith(";"):
            continue
        actions.append(discrete_from_json(line.strip("()").split()))
    return tuple(actions)


@dataclass
class SymbolicProposer:
    """Up to N task plans from a classical planner on the state's predicates."""

    time_limit_s: float = 20.0

    @property
    def name(self) -> str:
        return "symbolic:fast-downward"

    def propose(
        self, problem: Problem, state: State, literals: Iterable[GroundLiteral], n: int, seed: int
    ) -> Proposal:
        vocabulary = Vocabulary.from_problem(problem)
        start = time.perf_counter()
        plans: list[tuple[DiscreteAction, ...]] = []
        reasons: list[str] = []
        with tempfile.TemporaryDirectory(prefix="stalm-fd-") as folder:
            work = Path(folder)
            (work / "domain.pddl").write_text(domain_pddl())
            (work / "problem.pddl").write_text(
                problem_pddl(vocabulary, sorted(literals), goal_literals(problem), "state")
            )
            translate = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "fast_downward.translate",
                    "domain.pddl",
                    "problem.pddl",
                    "--sas-file",
                    "task.sas",
                ],
                cwd=work,
                capture_output=True,
                text=True,
                timeout=self.time_limit_s,
                check=False,
            )
            if translate.returncode != 0:
                raise StalmError(f"Fast Downward's translator failed: {translate.stderr[-400:]}")
            for index in range(n):
                plan_file = work / "sas_plan"
                plan_file.unlink(missing_ok=True)
                with (work / "task.sas").open() as task:
                    search = subprocess.run(
                        [str(downward_binary()), "--search", SEARCH.format(seed=seed + index)],
                        stdin=task,
                        cwd=work,
                        capture_output=True,
                        text=True,
                        timeout=self.time_limit_s,
                        check=False,
                    )
                if not plan_file.exists():
                    reasons.append(_why(search.stdout))
                    continue
                plan = _read_plan(plan_file.read_text(), vocabulary)
                if plan not in plans:
                    plans.append(plan)
        return Proposal(
            plans=tuple(plans),
            unparseable=tuple(reasons[:1]) if not plans else (),
            calls=0,
            seconds=time.perf_counter() - start,
        )


def _why(output: str) -> str:
    if "unsolvable" in output:
        return "the predicate abstraction of this state has no plan to the goal"
    return "Fast Downward found no plan in its time limit"
