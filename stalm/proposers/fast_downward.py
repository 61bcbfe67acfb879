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
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stalm import stopping
from stalm.domain.actions import DiscreteAction
from stalm.domain.serialize import discrete_from_json
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.pddl import domain_pddl, failure_name, problem_pddl
from stalm.llm.problem_prompt import goal_literals
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.feedback import FailedStep
from stalm.proposers.occlusion_cycles import without_occlusion_cycles
from stalm.proposers.protocol import Proposal, ProposalRequest
from stalm.proposers.task_objects import task_objects
from stalm.temp_folders import temporary_folder

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


def read_plan_steps(text: str) -> tuple[tuple[str, ...], ...]:
    """Fast Downward's plan file as ``(operator, arg, ...)`` tuples: one ``(op arg ...)`` per
    line, ``;`` comments skipped. Fast Downward writes names in lower case."""
    steps = []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith(";"):
            continue
        steps.append(tuple(line.strip("()").split()))
    return tuple(steps)


class DownwardGaveUp(Exception):
    """Fast Downward stopped without an answer for a reason that is data, not a bug: out of
    time or memory, or killed. A proposer turns it into an empty proposal."""


def translate_task(work: Path, time_limit_s: float) -> None:
    """Run Fast Downward's translator on ``domain.pddl`` and ``problem.pddl`` in ``work``,
    writing ``task.sas`` there. Raises :class:`DownwardGaveUp` when it runs out of memory or
    is killed, :class:`subprocess.TimeoutExpired` past ``time_limit_s``, and
    :class:`StalmError` with its message if it rejects the task (a bug in the PDDL)."""
    files = ["domain.pddl", "problem.pddl", "--sas-file", "task.sas"]
    translate = stopping.run_child(
        [sys.executable, "-m", "fast_downward.translate", *files],
        cwd=work,
        capture_output=True,
        text=True,
        timeout=time_limit_s,
    )
    if translate.returncode != 0:
        if "MemoryError" in translate.stderr or translate.returncode < 0:
            raise DownwardGaveUp(
                f"Fast Downward's translator ran out of memory or was killed "
                f"(exit {translate.returncode})"
            )
        raise StalmError(f"Fast Downward's translator failed: {translate.stderr[-400:]}")


@dataclass(frozen=True)
class SearchRun:
    """One run of Fast Downward's search on ``task.sas``: the plan file's text, or None."""

    plan: str | None
    output: str
    returncode: int = 0
    """The search's exit code (Fast Downward's: 11 unsolvable, 12 search incomplete, 22 out
    of memory; negative when killed by a signal)."""


def search_task(
    work: Path, search: str, time_limit_s: float, memory_limit_mb: int | None = None
) -> SearchRun:
    """Fast Downward's search binary with ``--search search`` on ``work/task.sas``.

    ``memory_limit_mb`` caps the search's address space (as Fast Downward's own driver does);
    a search that reaches it stops without a plan."""
    plan_file = work / "sas_plan"
    plan_file.unlink(missing_ok=True)

    with (work / "task.sas").open() as task:
        run = stopping.run_child(
            [str(downward_binary()), "--search", search],
            stdin=task,
            cwd=work,
            capture_output=True,
            text=True,
            timeout=time_limit_s,
            memory_limit_mb=memory_limit_mb,
        )
    if not plan_file.exists():
        return SearchRun(None, run.stdout, run.returncode)
    return SearchRun(plan_file.read_text(), run.stdout, run.returncode)


@dataclass
class SymbolicProposer:
    """Up to N task plans from a classical planner on the state's predicates.

    Given geometric feedback (:mod:`stalm.proposers.feedback`), the failed steps' facts join the
    init of the PDDL (whose domain understands them), so Fast Downward's next plans avoid what
    Concretize already found infeasible there. Fast Downward running out of time or memory,
    or being killed, is data: that call yields no plan and the reason is kept.
    """

    time_limit_s: float = 20.0
    goal_relations_only: bool = True
    """Ground a relative PLACE only for the goal's own relations (any other object goes *on*
    a region, which covers every spot a relative placement could name): far fewer choices
    and a grounding that grows linearly, not quadratically, with the objects."""
    break_occlusion_cycles: bool = True
    """When the abstraction has no plan, plan once more without the pick occlusions that lie
    on a cycle (:mod:`stalm.proposers.occlusion_cycles`); the proposal names them."""
    needed_objects_only: bool = True
    """Give Fast Downward only the movable objects an action on which can matter
    (:mod:`stalm.proposers.task_objects`): no plan is lost, and the grounding no longer
    grows with the clutter the predicates say nothing about. Only with
    ``goal_relations_only``: a relative PLACE next to a left-out object could be the one
    placement there that no occlusion or failure blocks."""

    @property
    def name(self) -> str:
        return "symbolic:fast-downward"

    @property
    def takes_feedback(self) -> bool:
        return True

    def propose(self, request: ProposalRequest) -> Proposal:
        query = _Query(self, request, Vocabulary.from_problem(request.problem))
        start = time.perf_counter()
        exact = [step for step in request.feedback if not step.is_rule]
        rules = [step for step in request.feedback if step.is_rule]
        base = set(request.literals) | {fact for step in exact for fact in step.facts}
        plans, reasons = query.plans(base, rules)
        set_aside: frozenset[GroundLiteral] = frozenset()
        if self.break_occlusion_cycles and not plans and not _gave_up(reasons):
            kept, set_aside = without_occlusion_cycles(base)
            if set_aside and not query.past():
                plans, more = query.plans(set(kept), rules)
                reasons += more
        return Proposal(
            plans=tuple(plans),
            no_plan=tuple(reasons[:1]) if not plans else (),
            calls=0,
            seconds=time.perf_counter() - start,
            set_aside=tuple(str(lit) for lit in sorted(set_aside)) if plans else (),
        )


_Found = tuple[list[tuple[DiscreteAction, ...]], list[str]]
"""Distinct plans, and the reasons of the Fast Downward runs that gave none."""


@dataclass(frozen=True)
class _Query:
    """The Fast Downward runs of one proposal: the proposer, its request and the vocabulary."""

    proposer: SymbolicProposer
    request: ProposalRequest
    vocabulary: Vocabulary

    def limit(self) -> float:
        """Each Fast Downward call gets its limit, or what is left before the deadline."""
        deadline, limit = self.request.deadline, self.proposer.time_limit_s
        return limit if deadline is None else max(0.5, min(limit, deadline - time.monotonic()))

    def past(self) -> bool:
        return self.request.deadline is not None and time.monotonic() >= self.request.deadline

    def plans(self, base: set[GroundLiteral], rules: Sequence[FailedStep]) -> _Found:
        """Up to ``n`` plans on ``base`` and the rules, giving the rules up when they leave
        no plan (:meth:`resolve`)."""
        seeds = [plan_seed(self.request.seed, index) for index in range(self.request.n)]
        plans, reasons = self.search(base, rules, seeds)
        if not plans and rules and not _gave_up(reasons):
            # the generalised rules contradict each other (P5: no can after the grill, and no
            # grill after a can drawn in front), and nothing here tells the wrong one: neither
            # its age (P5's wrong rules came first, P6's last) nor how often it failed
            # (FeedbackMemory). So the batch offers Concretize several resolutions at once, and
            # the counterexamples it and the search find refute the wrong rules for good.
            plans, reasons = self.resolve(base, rules)
        return plans, reasons

    def resolve(self, init: set[GroundLiteral], rules: Sequence[FailedStep]) -> _Found:
        """Up to ``n`` plans, the ``k``-th from the rules left after giving them up one by one
        in the order ``default_rng([seed, k])`` draws (``seed`` mod 2**64, as in
        :func:`plan_seed`), until Fast Downward finds a plan (each set of rules is searched
        once)."""
        n, seed = self.request.n, self.request.seed
        plans: list[tuple[DiscreteAction, ...]] = []
        reasons: list[str] = []
        found: dict[frozenset[int], list[tuple[DiscreteAction, ...]]] = {}
        for k in range(n):
            kept = list(np.random.default_rng([seed % 2**64, k]).permutation(len(rules)))
            while kept and not self.past():
                kept = kept[:-1]
                key = frozenset(int(i) for i in kept)
                if key not in found:
                    subset = [rules[i] for i in sorted(key)]
                    found[key], why = self.search(init, subset, [plan_seed(seed, n + k)])
                    reasons += why
                    if _gave_up(why):
                        return plans, reasons
                if found[key]:
                    if found[key][0] not in plans:
                        plans.append(found[key][0])
                    break
        return plans, reasons

    def search(
        self, init: set[GroundLiteral], rules: Sequence[FailedStep], seeds: Sequence[int]
    ) -> _Found:
        """One Fast Downward run per seed on ``init`` and the rules."""
        plans: list[tuple[DiscreteAction, ...]] = []
        reasons: list[str] = []
        if self.past():  # the caller stops with 'timeout'; no Fast Downward past it
            return plans, reasons
        relations_only = self.proposer.goal_relations_only
        goal = goal_literals(self.request.problem)
        facts = sorted(init | set(_rule_literals(rules)))
        vocabulary = self.vocabulary
        if self.proposer.needed_objects_only and relations_only:
            vocabulary, facts = task_objects(vocabulary, facts, goal)
        with temporary_folder("fd") as folder:
            work = Path(folder)
            (work / "domain.pddl").write_text(
                domain_pddl(feedback=True, goal_relations_only=relations_only)
            )
            (work / "problem.pddl").write_text(
                problem_pddl(vocabulary, facts, goal, "state", feedback=True, failures=len(rules))
            )
            try:
                translate_task(work, self.limit())
            except subprocess.TimeoutExpired:
                # cut by the trial's deadline: nothing to report (the caller times out)
                why = [] if self.past() else ["Fast Downward's translator hit its time limit"]
                return plans, why
            except DownwardGaveUp as error:
                return plans, [str(error)]
            for fd_seed in seeds:
                if self.past():
                    break
                try:
                    run = search_task(work, SEARCH.format(seed=fd_seed), self.limit())
                except subprocess.TimeoutExpired:
                    if not self.past():
                        reasons.append("Fast Downward found no plan in its time limit")
                    continue
                if run.plan is None:
                    reasons.append(_why(run))
                    continue
                plan = tuple(discrete_from_json(list(step)) for step in read_plan_steps(run.plan))
                if plan not in plans:
                    plans.append(plan)
        return plans, reasons


def plan_seed(query_seed: int, index: int) -> int:
    """Fast Downward's seed (a signed 32-bit number) for the ``index``-th search of a query.

    Drawn from both numbers rather than added, so that queries with consecutive seeds (STaLM's
    k-th proposal of a trial has seed base + k) share no search: asked again on an unchanged
    PDDL, the proposer draws five new plans instead of repeating four of the last five."""
    return int(np.random.SeedSequence([query_seed % 2**64, index]).generate_state(1)[0]) % 2**31


def _rule_literals(rules: Sequence[FailedStep]) -> list[GroundLiteral]:
    """``Forbids``/``ForbidsPick`` and ``Needs`` facts for the rules, one failure object each."""
    literals: list[GroundLiteral] = []
    for index, step in enumerate(rules):
        name = failure_name(index)
        if step.forbids is not None:
            literals.append(GroundLiteral("Forbids", (name, *step.forbids)))
        else:
            assert step.forbids_pick is not None
            literals.append(GroundLiteral("ForbidsPick", (name, *step.forbids_pick)))
        literals += [GroundLiteral("Needs", (name, other)) for other in step.besides]
    return literals


def _gave_up(reasons: Sequence[str]) -> bool:
    """Fast Downward stopped for time or memory (not for want of a plan): no rule is to blame."""
    return any("time limit" in r or "memory" in r for r in reasons)


def _why(run: SearchRun) -> str:
    """Why a search gave no plan, from its exit code (its own time limit is never set: the
    caller's timeout raises instead). Only time and memory count as giving up
    (:func:`_gave_up`); an exhausted or incomplete search blames the rules."""
    if run.returncode == 11 or "unsolvable" in run.output:
        return "the predicate abstraction of this state has no plan to the goal"
    if run.returncode == 22 or run.returncode < 0:
        return f"Fast Downward ran out of memory or was killed (exit {run.returncode})"
    if run.returncode == 23:
        return "Fast Downward found no plan in its time limit"
    if run.returncode == 12:
        return "Fast Downward's search stopped without a plan (incomplete search)"
    return f"Fast Downward's search failed without a plan (exit {run.returncode})"
