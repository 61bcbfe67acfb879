"""Where a solve is, shown on a terminal while it works; its decisions in the log.

:func:`solve_progress` gives the observer a solve hands to its planner
(:class:`~stalm.progress.TrialObserver`): on a terminal, one line kept up to date below the
output -- the phase, the real step of the horizon, the proposals and Concretize rounds so far,
how far the predicates are, the seconds spent of the budget -- and gone when the solve ends.
When the stream is not a terminal (a pipe, a file, CI), or with ``--quiet``, it shows nothing.
:func:`verbose_logging` sends the planners' per-step decisions (the ``stalm`` loggers, INFO) to
the same console for ``--verbose``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console, RenderableType
from rich.live import Live
from rich.spinner import Spinner
from rich.text import Text

from stalm.progress import QUIET, TrialObserver

PHASE_WORDS = {
    "setup": "building the scene",
    "predicates": "computing predicates",
    "proposer": "asking the proposer",
    "concretize": "concretizing task plans",
    "tree": "searching the tree",
    "execution": "executing",
}
"""What each phase is called on the progress line."""


class SolveProgress(TrialObserver):
    """The progress line of one solve (a rich renderable, drawn by :func:`solve_progress`'s
    live display from what the hooks were told last). It only remembers what it heard."""

    def __init__(self, title: str) -> None:
        self.title = title
        self.planner = ""
        self.problem = ""
        self.horizon = 0
        self.budget_s = 0.0
        self.start: float | None = None
        self.phase_name = ""
        self.done = 0
        self.proposals = 0
        self.proposer = ""
        self.rounds = 0
        self.plans = 0
        self.predicate_part = ""
        self.predicate_done = 0
        self.predicate_total = 0
        self.note = ""
        self.frames_done = 0
        self.frames_total = 0
        self._spinner = Spinner("dots")

    # ------------------------------------------------------------------ hooks
    def started(self, planner: str, problem: str, horizon: int, budget_s: float) -> None:
        self.planner, self.problem = planner, problem
        self.horizon, self.budget_s = horizon, budget_s
        self.start = time.monotonic()

    def phase(self, name: str) -> None:
        self.phase_name = name
        if name == "predicates":
            self.predicate_part = ""

    def step(self, done: int, horizon: int) -> None:
        self.done, self.horizon = done, horizon
        self.rounds = 0

    def proposal(self, number: int, proposer: str) -> None:
        self.proposals, self.proposer = number + 1, proposer
        self.phase_name = "proposer"

    def concretize(self, round_: int, plans: int) -> None:
        self.rounds, self.plans = round_ + 1, plans

    def predicates(self, part: str, done: int, total: int) -> None:
        self.predicate_part, self.predicate_done, self.predicate_total = part, done, total

    def frames(self, done: int, total: int) -> None:
        self.phase_name = "frames"
        self.frames_done, self.frames_total = done, total

    def message(self, text: str) -> None:
        """A planner's own words (a baseline's, or PDDLStream's, which send no structured
        events): shown as the line itself before the trial starts, else at its end."""
        self.note = text

    # ------------------------------------------------------------------ the line
    def line(self) -> str:
        """The progress line as text (what the terminal shows beside the spinner)."""
        if self.phase_name == "frames":
            return f"rendering the animation: frame {self.frames_done} of {self.frames_total}"
        if self.start is None:
            return self.note or self.title
        parts = [f"{self.problem} with {self.planner}", f"step {self.done + 1} of {self.horizon}"]
        doing = PHASE_WORDS.get(self.phase_name, self.phase_name or "starting")
        if self.phase_name == "predicates" and self.predicate_part:
            of = f" of {self.predicate_total}" if self.predicate_total else ""
            doing += f" ({self.predicate_part} {self.predicate_done}{of})"
        elif self.phase_name == "proposer" and self.proposer:
            doing = f"asking {self.proposer}"
        elif self.phase_name == "concretize" and self.rounds:
            doing += f" (round {self.rounds}, {self.plans} plans)"
        parts.append(doing)
        if self.proposals:
            parts.append(f"{self.proposals} proposal{'s' if self.proposals != 1 else ''}")
        elapsed = time.monotonic() - self.start
        parts.append(f"{elapsed:.0f} s of {self.budget_s:.0f} s")
        if self.note and not self.phase_name:
            parts.append(self.note)
        return " · ".join(parts)

    def __rich__(self) -> RenderableType:
        self._spinner.update(text=Text(self.line(), overflow="ellipsis", no_wrap=True))
        return self._spinner


def shows_progress(console: Console, quiet: bool) -> bool:
    """Whether a progress line goes to ``console``: on a terminal, unless ``--quiet``."""
    return not quiet and console.is_terminal and not console.is_dumb_terminal


@contextmanager
def solve_progress(console: Console, title: str, quiet: bool = False) -> Iterator[TrialObserver]:
    """The observer of one solve: a live line on ``console`` while the block runs if it is a
    terminal and not ``quiet`` (:func:`shows_progress`), else one that shows nothing."""
    if not shows_progress(console, quiet):
        yield QUIET
        return
    progress = SolveProgress(title)
    with Live(progress, console=console, transient=True, refresh_per_second=8):
        yield progress


@contextmanager
def verbose_logging(console: Console, verbose: bool) -> Iterator[None]:
    """With ``verbose``, the ``stalm`` loggers' INFO records (each real step's decisions) go to
    ``console`` while the block runs; without, nothing changes."""
    if not verbose:
        yield
        return
    from rich.logging import RichHandler

    logger = logging.getLogger("stalm")
    handler = RichHandler(console=console, show_path=False, show_time=False, markup=False)
    handler.setFormatter(logging.Formatter("%(message)s"))
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
