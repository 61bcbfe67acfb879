"""A trial's deadline as a predicate computation sees it: a question asked between samples.

Predicates cost motion planning; on a problem with many objects the first computation takes
longer than a short time budget. So :class:`~stalm.predicates.engine.PredicateEngine` asks
the deadline between its samples (each a fraction of a second) and, once it has passed, gives
the computation up by raising :exc:`DeadlinePassed`: what it had computed is dropped, never
returned as a state's predicates. The deadline is a callable, not a time, because a trial's
deadline moves (a reply served from the cache moves it earlier,
:meth:`stalm.trial.episode.Episode.charge`).
"""

from __future__ import annotations

from collections.abc import Callable

Deadline = Callable[[], bool]
"""True once the deadline has passed (e.g. :meth:`stalm.trial.episode.Episode.out_of_time`)."""


class DeadlinePassed(Exception):
    """A predicate computation was given up at its deadline; nothing it computed is kept.

    Not a :class:`stalm.errors.StalmError`: no input is at fault, the time ran out. The
    online loop ends the trial as 'timeout' when it sees one."""


def check(deadline: Deadline | None) -> None:
    """Raise :exc:`DeadlinePassed` if ``deadline`` (None: none) has passed."""
    if deadline is not None and deadline():
        raise DeadlinePassed("the deadline passed during a predicate computation")
