"""What a run tells whoever watches it: where a trial is, as it goes.

A planner, its trial loop, the predicate memo and the animation writer report what they are
doing to a :class:`TrialObserver` handed to them (``stalm solve`` shows it on a terminal,
:mod:`stalm.cli.solve_progress`). An observer only listens: every hook returns nothing, is
called after the decision it reports was made, and no planner reads anything back from it, so
a run observed and a run not observed make the same decisions and the same random draws. The
base class's hooks do nothing; an observer overrides the ones it shows.

A plain function of one string (:data:`Progress`, what planners took before there was an
observer) is still accepted wherever an observer is: :func:`observer_of` makes it one that
hears every message.

This module sits beside :mod:`stalm.errors`, outside the layers, so that every layer (the
predicates' engine as much as the planners) can report to the one observer of a run.
"""

from __future__ import annotations

from collections.abc import Callable

Progress = Callable[[str], None]
"""A function that hears what a planner says it is doing, as one line of text."""


class TrialObserver:
    """Hears what a trial is doing (see the module docstring). Each hook does nothing here.

    An observer is also a :data:`Progress` function: calling it with a line of text is
    :meth:`message`, so it can be handed to any planner or command that takes one."""

    def __call__(self, text: str) -> None:
        self.message(text)

    def started(self, planner: str, problem: str, horizon: int, budget_s: float) -> None:
        """A trial of ``planner`` on ``problem`` began: at most ``horizon`` real steps within
        ``budget_s`` seconds."""

    def phase(self, name: str) -> None:
        """The trial entered phase ``name`` (a field of
        :class:`~stalm.trial.result.PhaseTimes`: setup, predicates, proposer, concretize,
        tree, execution), or came back to it from a phase nested inside it."""

    def step(self, done: int, horizon: int) -> None:
        """A real step begins with ``done`` actions executed of at most ``horizon``."""

    def proposal(self, number: int, proposer: str) -> None:
        """The proposer is asked for task plans (``number``: the trial's proposals before)."""

    def concretize(self, round_: int, plans: int) -> None:
        """Concretize grounds ``plans`` task plans of the step's proposal round ``round_``."""

    def predicates(self, part: str, done: int, total: int) -> None:
        """Of a state's predicates, ``done`` of ``total`` items of ``part`` (picks,
        placements, ...) are computed; ``total`` 0 when it is not known in advance."""

    def frames(self, done: int, total: int) -> None:
        """``done`` of ``total`` frames of an animation are rendered."""

    def message(self, text: str) -> None:
        """Anything else worth a line (what a baseline's step is doing)."""


class MessageObserver(TrialObserver):
    """An observer that passes every message to a :data:`Progress` function, and only those."""

    def __init__(self, progress: Progress) -> None:
        self._progress = progress

    def message(self, text: str) -> None:
        self._progress(text)


QUIET = TrialObserver()
"""The observer that shows nothing (it holds no state: one is enough)."""


def observer_of(progress: Progress | TrialObserver | None) -> TrialObserver:
    """``progress`` as an observer: itself if it is one, a :class:`MessageObserver` if it is
    a function of one string, :data:`QUIET` for None."""
    if progress is None:
        return QUIET
    if isinstance(progress, TrialObserver):
        return progress
    return MessageObserver(progress)
