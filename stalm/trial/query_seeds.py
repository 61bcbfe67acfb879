"""The seeds of a trial's model queries, all derived here from the trial's seed.

Three derivations, by what a query is about:

* a baseline's query at a real step (EP-SayCan, Iterative-Replanning): :func:`query_seed`, a
  :class:`numpy.random.SeedSequence` of (trial seed, step, attempt), which never collides;
* STaLM's proposals: :func:`stalm_proposal_seed`, ``trial seed * 1000 + proposal``. It
  collides once a trial makes 1000 proposals (no trial at the paper's budgets comes near),
  and :func:`stalm.experiments.trials.derive_seed` keeps trial seeds below 2**20 so it stays
  below 2**31. Every recorded STaLM trial and reply cache was made with it: moving it to
  :func:`query_seed` changes which cached replies a STaLM trial finds and the plans of every
  golden STaLM case, so it is kept until those are recorded again;
* LLM-MCTS's prior at a search node: :func:`state_request_seed`, a hash of the node's state,
  since a node is asked once whatever step creates it.

Every value is below 2**31, so it fits every backend and the reply cache's integer column.
(The queries themselves are :func:`stalm.proposers.language_model.ask_for_task_plans`.)
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

from stalm.world.state import State


def query_seed(trial_seed: int, step: int, attempt: int) -> int:
    """The backend seed of a baseline's query at ``step``, try ``attempt`` (never colliding,
    unlike ``seed * 1000 + step``-style arithmetic)."""
    sequence = np.random.SeedSequence([trial_seed, step, attempt])
    return int(sequence.generate_state(1, dtype=np.uint32)[0] >> 1)


def stalm_proposal_seed(trial_seed: int, proposals: int) -> int:
    """The seed of STaLM's query after ``proposals`` earlier ones in the trial (see the
    module docstring for why it is not :func:`query_seed`)."""
    return trial_seed * 1000 + proposals


def state_request_seed(trial_seed: int, state: State) -> int:
    """The backend seed for LLM-MCTS's prior at ``state`` in trial ``trial_seed``.

    A SHA-256 of the state's JSON form (coordinates are quantised, keys sorted) is stable
    across processes and machines, unlike ``hash()``; ``seed + 4`` for the fifth sample stays
    below 2**31 too.
    """
    text = json.dumps(["llm-mcts-prior", trial_seed, state.to_json()], sort_keys=True)
    digest = hashlib.sha256(text.encode()).digest()
    return int.from_bytes(digest[:4], "little") >> 1
