"""What the search needs of a problem: the interface :class:`stalm.domain.mdp.Domain` offers.

Search code depends only on this protocol, so its mechanics are tested on small synthetic
MDPs (test doubles under ``tests/``) and run unchanged on the PyBullet domain.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from stalm.domain.actions import DiscreteAction
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.domain.params import Action
from stalm.world.state import State


class SearchMDP(Protocol):
    """The G-TAMP MDP as the search sees it (see :class:`stalm.domain.mdp.Domain`)."""

    def legal_actions(self, state: State) -> tuple[DiscreteAction, ...]:
        """Discrete actions whose symbolic preconditions hold in ``state``."""
        ...

    def precondition_failure(self, state: State, action: DiscreteAction) -> str | None:
        """Why ``action``'s symbolic precondition is false (None if it holds)."""
        ...

    def sample(
        self, state: State, action: DiscreteAction, rng: np.random.Generator
    ) -> Action | Infeasibility:
        """ψ: continuous parameters for ``action`` (with the operator's tries), or why none."""
        ...

    def step(self, state: State, action: Action) -> Outcome:
        """T and R for a sampled feasible action."""
        ...

    def infeasible(self, state: State, why: Infeasibility) -> Outcome:
        """The absorbing failure outcome (s' = s, reward -6)."""
        ...

    def sample_and_step(
        self, state: State, action: DiscreteAction, rng: np.random.Generator
    ) -> tuple[Action | None, Outcome]: ...

    def is_goal(self, state: State) -> bool: ...
