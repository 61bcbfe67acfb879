"""Seeds of the baselines' model queries (the query itself is
:func:`stalm.proposers.language_model.ask_for_task_plans`, shared with STaLM)."""

from __future__ import annotations

import numpy as np


def query_seed(trial_seed: int, step: int, attempt: int) -> int:
    """The backend seed of one query, derived from the trial seed, the step and the attempt.

    A :class:`numpy.random.SeedSequence` of the three numbers gives seeds that never collide
    for different (step, attempt) pairs, unlike ``seed * 1000 + step``-style arithmetic, and
    stays below 2**31 so it fits every backend and the reply cache's integer column.
    """
    sequence = np.random.SeedSequence([trial_seed, step, attempt])
    return int(sequence.generate_state(1, dtype=np.uint32)[0] >> 1)
