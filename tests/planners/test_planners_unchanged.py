"""Behaviour-unchanged golden test: every planner of ``stalm planners`` on short, seeded runs.

Each case builds its planner through the registry (as ``stalm solve`` does), runs one trial on a
copy of a problem with a horizon of 1 or 2 and a few simulations per step, and compares what
was executed -- the discrete actions with every continuous parameter, the final state, the
termination, the counters (but collision checks), the failure kinds of the offered plans and
the keys of ``details`` -- with ``data/planners_unchanged.json``. Wall-clock budgets are far
above what the runs take, so no case depends on the machine's speed. Discrete parts (actions,
termination, counters, failure kinds, decisions) compare exactly and continuous values within
:data:`~stalm.geometry.tolerance.CONTINUOUS_TOLERANCE`, so the file holds on another CPU, whose
IK solutions and trigonometry differ in the last bits (by ~1e-11: see
``tests/test_behaviour_unchanged.py`` for where; a plan's arm waypoints were the first place
such a difference showed). ``tests/test_golden_perturbed.py`` reruns every case with those
bits moved. Planners that ask a
language model get :class:`ScriptedReplyBackendDouble` in place of the configured backend
(scripted replies, :data:`REPLIES`), with the reply cache off.

A change meant to keep behaviour (a refactor) must leave this file passing. A change meant to
alter behaviour regenerates the file on purpose::

    PYTHONPATH=. python -m tests.planners.test_planners_unchanged

and says why in its commit. The slow cases (stalm-symbolic and uct on the problems other than P2,
each paying for its own scene) run with ``pytest -m slow``.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

import stalm.llm.backends as backends
from stalm.domain.actions import DiscreteAction
from stalm.llm.prompt import PromptOptions
from stalm.planners.registry import build_planner
from stalm.world.problem import Problem, load_problem
from tests.flat_settings import settings_of
from tests.golden import assert_matches, read, write
from tests.planners.llm_reply_doubles import ScriptedReplyBackendDouble, plan_reply
from tests.planners.test_stalm import P2_PLAN

GOLDEN = Path(__file__).parent / "data" / "planners_unchanged.json"

P2_PLAN_WITHOUT_OPEN = P2_PLAN[1:]
"""The scripted reply by default: Concretize fails it at its first step (the door is shut)."""

REPLIES: dict[str, tuple[tuple[DiscreteAction, ...], ...]] = {
    "without_open": (P2_PLAN_WITHOUT_OPEN,),
    "both": (P2_PLAN, P2_PLAN_WITHOUT_OPEN),
}
"""Reply texts by name (a request for n replies gets them cycled). STaLM w/o UCT,
Iterative-Replanning and LLM-MCTS get "both": with only a plan that fails at its first step
they may never execute anything and ask again until the clock ends the trial (LLM-MCTS's prior
then sends all of a few simulations to infeasible actions), and once the door is open the plan
with the OPEN fails at its first step."""

WALL_BUDGET_S = 3600.0
"""Far above any case's run time: no case may end by the clock."""


@dataclass(frozen=True)
class Case:
    """One seeded trial: a planner by name, a problem, a horizon, the config's overrides."""

    planner: str
    problem: str
    horizon: int
    seed: int
    config: dict[str, Any] = field(default_factory=dict)
    slow: bool = False
    reply: str = "without_open"
    """The scripted reply (:data:`REPLIES`) of a planner that asks a model."""

    @property
    def key(self) -> str:
        extra = ",".join(f"{k}={v}" for k, v in sorted(self.config.items()))
        reply = "" if self.reply == "without_open" else f"/reply={self.reply}"
        return f"{self.planner}[{extra}]/{self.problem}/h{self.horizon}/s{self.seed}{reply}"


# The tree planners execute by the authors' 'best_q' rule here: the 'progress' rule searches on
# until the step's share of the wall-clock budget is spent when no root action leads to goal
# progress (as in a horizon too short for any), which would make a case depend on the clock.
_BEST_Q = {"execution": "best_q"}
_NO_OCCLUSION = PromptOptions(occlusion_predicates=False)
_SYMBOLIC = {"proposer": "symbolic", "sims": 4, **_BEST_Q}
CASES: tuple[Case, ...] = (
    Case("stalm", "P2", 2, 4, _SYMBOLIC),
    Case("stalm", "P2", 2, 4, {"sims": 4, **_BEST_Q}),
    Case("stalm", "P2", 2, 4, {"sims": 4, "reuse_tree": False, **_BEST_Q}),
    Case("stalm-no-uct", "P2", 2, 4, {}, reply="both"),
    Case("uct", "P2", 2, 1, {"sims": 6, **_BEST_Q}),
    Case("uct-hcount", "P2", 1, 0, {"sims": 2, **_BEST_Q}),
    Case("ep-saycan", "P2", 2, 0, {}),
    Case("iterative-replanning", "P2", 1, 0, {}, reply="both"),
    # without occlusion literals: LLM-MCTS computes every new node's predicates
    Case("llm-mcts", "P2", 1, 0, {"sims": 3, "batch": 2, "prompt": _NO_OCCLUSION}, reply="both"),
    Case("pddlstream-adaptive", "P2", 1, 0, {}),
    *(
        Case("uct", name, 1, 0, {"sims": 3, **_BEST_Q}, slow=True)
        for name in ("P1", "P3", "P4", "P5", "P6")
    ),
    *(Case("stalm", name, 1, 0, _SYMBOLIC, slow=True) for name in ("P1", "P3", "P4", "P5", "P6")),
)


@contextmanager
def scripted_backend(reply: str) -> Iterator[None]:
    """Every backend the registry makes is the scripted double answering ``REPLIES[reply]``
    (the real ``make_backend`` is restored afterwards)."""
    real = backends.make_backend

    def make(spec: str | None = None, **_: object) -> ScriptedReplyBackendDouble:
        return ScriptedReplyBackendDouble(queue=[[plan_reply(plan) for plan in REPLIES[reply]]])

    backends.make_backend = make  # type: ignore[assignment]
    try:
        yield
    finally:
        backends.make_backend = real


def _short(problem: Problem, horizon: int) -> Problem:
    return Problem(problem.spec.model_copy(update={"horizon": horizon}), problem.source)


def run_case(case: Case, problem: Problem) -> dict[str, Any]:
    """What the golden file keeps of one case's trial."""
    config = settings_of(llm="scripted", cache_mode="off", **case.config)
    with scripted_backend(case.reply):
        planner = build_planner(case.planner, config)
    result = planner.solve(_short(problem, case.horizon), case.seed, WALL_BUDGET_S)
    data = json.loads(json.dumps(result.to_json()))
    # collision checks also count those made building a roadmap the disk cache did not hold
    # yet, so they depend on which case ran first, not on what the planner did
    counters = {k: v for k, v in data["counters"].items() if k != "collision_checks"}
    return {
        "planner": data["planner"],
        "termination": data["termination"],
        "success": data["success"],
        "plan": data["plan"],
        "final_state": data["final_state"],
        "counters": counters,
        "llm_plan_failures": data["llm_plan_failures"],
        "details_keys": sorted(data["details"]),
        "decisions": [step.get("decision") for step in data["details"].get("step_log", [])],
    }


def _golden() -> dict[str, Any]:
    return read(GOLDEN)


@pytest.mark.parametrize(
    "case",
    [pytest.param(c, id=c.key, marks=[pytest.mark.slow] if c.slow else []) for c in CASES],
)
def test_planner_behaviour_is_unchanged(case: Case, problems: dict[str, Problem]) -> None:
    expected = _golden()[case.key]
    assert_matches(run_case(case, problems[case.problem]), expected)


def test_the_golden_file_covers_every_planner_of_the_registry() -> None:
    from stalm.planners.registry import planners

    assert set(_golden()) == {case.key for case in CASES}
    assert {case.planner for case in CASES} == set(planners())


def regenerate(only: tuple[str, ...] = ()) -> None:
    """Run every case (or those whose key starts with one of ``only``) and rewrite the file
    after each one (the fast cases first)."""
    golden = _golden() if GOLDEN.exists() else {}
    keys = {case.key for case in CASES}
    loaded: dict[str, Problem] = {}
    for case in sorted(CASES, key=lambda c: c.slow):
        if only and not case.key.startswith(only):
            continue
        problem = loaded.setdefault(case.problem, load_problem(case.problem))
        golden[case.key] = run_case(case, problem)
        print(case.key, golden[case.key]["termination"], golden[case.key]["counters"])
        kept = {k: golden[k] for k in sorted(golden) if k in keys}
        write(GOLDEN, kept)


if __name__ == "__main__":
    import os
    import tempfile

    # roadmaps go to a fresh folder, as in the tests, never the user's cache
    os.environ["STALM_CACHE_DIR"] = tempfile.mkdtemp(prefix="stalm-golden-")
    regenerate(tuple(sys.argv[1:]))
