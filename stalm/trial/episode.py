"""The bookkeeping of one online trial (kept by :class:`stalm.trial.online.OnlinePlanner`).

Every online planner does the same things around its decisions: one wall-clock deadline for the
whole trial, the executed actions and the states they lead to, wall time per phase, what the
language model cost, the failure kinds of the task plans it offered, and at the end a replay of
the executed plan in a fresh scene (a plan that fails there is a failure, never a success) turned
into a :class:`PlanResult`. :class:`Episode` holds exactly that, so a method's module is only
its decision rule.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

from stalm.domain.mdp import Domain
from stalm.domain.params import Action
from stalm.predicates.engine import PredicateCache, PredicateEngine
from stalm.predicates.memo import PredicateMemo
from stalm.progress import QUIET, TrialObserver
from stalm.proposers.protocol import Proposal
from stalm.search.concretize import ConcretizeResult
from stalm.search.failure_kinds import figure5_kinds
from stalm.trial.details import MethodDetails, QueryRecord, ReplayCheck, RunDetails
from stalm.trial.replay import replay_plan
from stalm.trial.result import Counters, PhaseTimes, PlanResult, cpu_seconds
from stalm.world.problem import Problem
from stalm.world.state import State


@dataclass
class PhaseClock:
    """Seconds spent per phase so far (mutable: the loop adds to it).

    Phases nest: LLM-MCTS asks its prior and Hcount computes predicates from inside the tree
    search, and those seconds are the prior's and the predicates', not the search's. So a
    block timed by :meth:`timed` is charged its wall time less what the blocks timed inside it
    took.
    """

    predicates: float = 0.0
    proposer: float = 0.0
    concretize: float = 0.0
    tree: float = 0.0
    execution: float = 0.0
    setup: float = 0.0
    observer: TrialObserver = field(default=QUIET, repr=False, compare=False)
    """Told each phase the trial enters, and the one it comes back to (it only listens)."""
    _inner: list[float] = field(default_factory=list, repr=False)
    """Per running :meth:`timed` block: the seconds of the blocks timed inside it so far."""
    _names: list[str | None] = field(default_factory=list, repr=False)
    """Per running :meth:`timed` block: its phase."""

    @contextmanager
    def timed(self, phase: str | None) -> Iterator[None]:
        """Charge the block's wall time, less that of blocks timed inside it, to ``phase``.

        ``None`` charges nothing: for time another record accounts for (a model query, whose
        seconds :meth:`Episode.record_query` charges), taken out of the enclosing phase.
        """
        self._inner.append(0.0)
        self._names.append(phase)
        if phase is not None:
            self.observer.phase(phase)
        tick = time.monotonic()
        try:
            yield
        finally:
            elapsed = time.monotonic() - tick
            inner = self._inner.pop()
            self._names.pop()
            if phase is not None:
                setattr(self, phase, getattr(self, phase) + elapsed - inner)
            if self._inner:
                self._inner[-1] += elapsed
            outer = next((name for name in reversed(self._names) if name is not None), None)
            if phase is not None and outer is not None and outer != phase:
                self.observer.phase(outer)  # back in the phase this one was nested in


@dataclass
class Episode:
    """One trial in progress: where the robot is, what it did, and what that cost.

    Time is charged as the trial would have taken without the reply cache: a query is counted
    at the seconds its replies took when they were made (:attr:`Proposal.original_seconds`),
    and the difference to what it took now moves the trial's start and deadline earlier. So a
    trial's time, its LLM time and whether it ends within its budget do not depend on which
    earlier run happened to fill the cache; a replayed run shows the time of the run it
    replays.
    """

    problem: Problem
    start_time: float
    deadline: float
    state: State
    executed: list[Action] = field(default_factory=list)
    states: list[State] = field(default_factory=list)
    clock: PhaseClock = field(default_factory=PhaseClock)
    failures: Counter[str] = field(default_factory=Counter)
    llm_calls: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    queries: list[QueryRecord] = field(default_factory=list)
    memo: PredicateMemo | None = None
    """The trial's predicates by state, the one store every part of the trial asks
    (:meth:`keep_predicates`; None until then)."""
    cpu_start: float = field(default_factory=cpu_seconds)
    """:func:`cpu_seconds` when the trial began."""

    @staticmethod
    def begin(
        problem: Problem, time_budget_s: float | None, observer: TrialObserver = QUIET
    ) -> Episode:
        """A trial starting now from the problem's initial state (budget None: the problem's);
        ``observer`` hears each phase it enters and each predicate computation's progress."""
        start = time.monotonic()
        budget = time_budget_s if time_budget_s is not None else problem.spec.time_budget_s
        state = problem.initial_state
        clock = PhaseClock(observer=observer)
        return Episode(problem, start, start + budget, state, states=[state], clock=clock)

    @property
    def observer(self) -> TrialObserver:
        return self.clock.observer

    def out_of_time(self) -> bool:
        return time.monotonic() >= self.deadline

    def stop_reason(self, domain: Domain) -> str | None:
        """'goal', 'horizon' or 'timeout' when the trial must stop now, else None."""
        if domain.is_goal(self.state):
            return "goal"
        if len(self.executed) >= self.problem.horizon:
            return "horizon"
        if self.out_of_time():
            return "timeout"
        return None

    def keep_predicates(self, engine: PredicateEngine) -> PredicateMemo:
        """The trial's predicate memo, computing with ``engine``: timed by this episode's
        clock as the 'predicates' phase and bounded by its deadline."""
        self.memo = PredicateMemo(engine, self.clock, self.out_of_time, self.observer.predicates)
        return self.memo

    def predicates(self) -> PredicateCache:
        """The current state's predicates, from the trial's memo (:meth:`keep_predicates`).

        Computed from scratch once; after that brought forward through every action executed
        since the last call with Appendix A's cached update (equal to a full computation), so
        a planner asking once per step pays only for what its actions changed.
        """
        if self.memo is None:
            raise RuntimeError("the episode keeps no predicates yet (keep_predicates)")
        return self.memo.along(self.states, self.executed)

    def count_failures(self, concrete: ConcretizeResult) -> None:
        """Add the Figure 5 kinds of the task plans Concretize could not take to the goal.

        They were tried from the current state, whose predicates (the prompt's init) decide
        whether a failed first step was occluded, i.e. a precondition violation
        (:mod:`stalm.search.failure_kinds`).
        """
        if not concrete.failures:
            return
        current = self.memo.known(self.state) if self.memo is not None else None
        if current is None:
            raise RuntimeError("count_failures needs the current state's predicates")
        self.failures.update(figure5_kinds(concrete, current.literals))

    def record_query(self, proposal: Proposal) -> None:
        """Add one language-model query's calls, tokens and seconds (its original seconds,
        see the class docstring), and keep its :class:`QueryRecord`."""
        self.llm_calls += proposal.calls
        self.prompt_tokens += proposal.prompt_tokens
        self.completion_tokens += proposal.completion_tokens
        self.clock.proposer += proposal.original_seconds
        self.charge(proposal.original_seconds - proposal.seconds)
        self.queries.append(
            QueryRecord(
                proposal.from_cache,
                proposal.seconds,
                proposal.original_seconds,
                len(proposal.plans),
                proposal.truncated_plans,
            )
        )

    def charge(self, seconds: float) -> None:
        """Count ``seconds`` as spent although the wall clock did not see them pass (the
        original time of replies served from the cache): the trial started that much earlier
        and its deadline comes that much sooner."""
        self.start_time -= seconds
        self.deadline -= seconds

    def execute(self, domain: Domain, action: Action) -> None:
        """Apply a sampled action that ψ found feasible in the current state."""
        with self.clock.timed("execution"):
            outcome = domain.step(self.state, action)
        self.state = outcome.state
        self.executed.append(action)
        self.states.append(self.state)

    def finish(
        self,
        domain: Domain | None,
        planner: str,
        seed: int,
        termination: str,
        *,
        simulations: int = 0,
        replans: int = 0,
        details: MethodDetails | None = None,
    ) -> PlanResult:
        """The trial's result; a 'goal' run is replayed in a fresh scene before it counts.
        ``domain`` is None for a trial whose deadline passed before its scene was built."""
        replay_reason = None
        if termination == "goal":
            tick = time.monotonic()
            report = replay_plan(self.problem, self.problem.initial_state, self.executed)
            self.clock.execution += time.monotonic() - tick
            replay_reason = report.reason
            if not report.reached_goal:
                termination = "replay_failed"
        clock = self.clock
        total = time.monotonic() - self.start_time
        return PlanResult(
            problem=self.problem.name,
            planner=planner,
            seed=seed,
            success=termination == "goal",
            plan=tuple(self.executed),
            states=tuple(self.states),
            times=PhaseTimes(
                clock.predicates,
                clock.proposer,
                clock.concretize,
                clock.tree,
                clock.execution,
                total,
                cpu_seconds() - self.cpu_start,
                clock.setup,
            ),
            counters=Counters(
                llm_calls=self.llm_calls,
                prompt_tokens=self.prompt_tokens,
                completion_tokens=self.completion_tokens,
                transitions=domain.counters.transitions if domain else 0,
                samples=domain.counters.samples if domain else 0,
                collision_checks=domain.sim.collision_checks if domain else 0,
                simulations=simulations,
                replans=replans,
            ),
            termination=termination,
            llm_plan_failures=dict(self.failures),
            details=RunDetails(details, ReplayCheck(replay_reason), tuple(self.queries)),
        )
