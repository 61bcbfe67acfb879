"""One trial's geometric predicates, by state: computed once, brought forward along actions.

Predicates cost motion planning (seconds per state), and an online planner needs them in
several places: the prompt of the current state, Hcount at every leaf of the search, the
LLM-MCTS prior at every new node. :class:`PredicateMemo` is the one store a trial keeps for
all of them. A state's predicates are derived from its parent's with Appendix A's cached
update (:meth:`PredicateEngine.update`, equal to a full computation and several times cheaper)
when the action between them is known, and computed from scratch otherwise; either way they
are kept for the rest of the trial, since later steps' trees revisit earlier states.

Every computation is bounded by the trial's deadline: past it the engine gives up between two
samples (:exc:`~stalm.predicates.deadline.DeadlinePassed`, which the online loop turns into
the trial's 'timeout'), and nothing of the computation is kept, so the memo holds only
complete predicates.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import AbstractContextManager, nullcontext
from typing import Protocol

from stalm.predicates.deadline import Deadline
from stalm.predicates.engine import ActionTuple, PredicateCache, PredicateEngine, Report
from stalm.world.problem import Problem
from stalm.world.state import State


class Timing(Protocol):
    """Where computations are timed by phase (:class:`stalm.trial.episode.PhaseClock`)."""

    def timed(self, phase: str | None) -> AbstractContextManager[None]: ...


class Executed(Protocol):
    """An executed action as the memo needs it: its discrete part (a
    :class:`stalm.domain.params.Action`; the domain is a sibling layer predicates may not
    import)."""

    @property
    def discrete(self) -> ActionTuple: ...


class PredicateMemo:
    """The predicates of every state a trial asked about (see the module docstring).

    ``timing`` charges each computation to the trial's 'predicates' phase (the trial's
    clock; None: nothing is timed). ``deadline`` bounds every computation (the trial's;
    None: none). ``report`` hears how far a computation is (None: nobody).
    ``computed_from_scratch`` and ``brought_forward`` count the two kinds of computation.
    """

    def __init__(
        self,
        engine: PredicateEngine,
        timing: Timing | None = None,
        deadline: Deadline | None = None,
        report: Report | None = None,
    ) -> None:
        self.engine = engine
        self.timing = timing
        self.deadline = deadline
        self.report = report
        """Hears how far each computation is (:data:`~stalm.predicates.engine.Report`)."""
        self._known: dict[State, PredicateCache] = {}
        self.computed_from_scratch = 0
        self.brought_forward = 0

    @property
    def problem(self) -> Problem:
        return self.engine.problem

    def known(self, state: State) -> PredicateCache | None:
        """The predicates of ``state`` if they were computed, else None (nothing computed)."""
        return self._known.get(state)

    def of(
        self, state: State, parent: State | None = None, action: ActionTuple | None = None
    ) -> PredicateCache:
        """The predicates of ``state``: kept ones, else brought forward from ``parent``'s
        through ``action`` (which leads from ``parent`` to ``state``), else from scratch.
        Raises :exc:`~stalm.predicates.deadline.DeadlinePassed` (and keeps nothing new) once
        the deadline has passed during a computation."""
        known = self._known.get(state)
        if known is not None:
            return known
        if parent is None or action is None:
            with self._timed():
                cache = self.engine.compute(state, self.deadline, self.report)
            self.computed_from_scratch += 1
        else:
            before = self.of(parent)
            with self._timed():
                cache = self.engine.update(before, action, state, self.deadline, self.report)
            self.brought_forward += 1
        self._known[state] = cache
        return cache

    def _timed(self) -> AbstractContextManager[None]:
        return self.timing.timed("predicates") if self.timing is not None else nullcontext()

    def along(self, states: Sequence[State], executed: Sequence[Executed]) -> PredicateCache:
        """The predicates of ``states[-1]``, the end of an executed path (``states[i + 1]``
        is where ``executed[i]`` led): brought forward step by step from the last state of
        the path whose predicates are kept (from scratch at ``states[0]`` if none is)."""
        start = len(states) - 1
        while start > 0 and states[start] not in self._known:
            start -= 1
        cache = self.of(states[start])
        for index in range(start, len(executed)):
            cache = self.of(states[index + 1], states[index], executed[index].discrete)
        return cache
