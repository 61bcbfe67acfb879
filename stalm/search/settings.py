"""The search's hyperparameters, with the paper's values as defaults (§4.2, Appendix B).

One frozen object carries them so a run can be reproduced from its JSON record and the CLI can
override any of them by name. Values a user can get wrong raise :class:`~stalm.errors.StalmError`
naming the field, because a silently clamped constant would change what an experiment measures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from stalm.errors import StalmError


@dataclass(frozen=True)
class SearchSettings:
    """UCT, progressive-widening and episode constants of WarmStartedUCT.

    ``c`` is the UCT exploration constant (applied to raw, unnormalised returns, so it is large),
    ``k`` and ``alpha`` the progressive-widening constants (k_α, c_α), ``gamma`` the discount,
    ``horizon`` the episode length H counted from the episode start (not from the search root),
    and ``budget`` the number of simulations N_budget.
    """

    c: float = 50.0
    k: float = 1.5
    alpha: float = 0.15
    gamma: float = 0.99
    horizon: int = 20
    budget: int = 30

    def __post_init__(self) -> None:
        checks: tuple[tuple[str, bool, str], ...] = (
            ("c", math.isfinite(self.c) and self.c >= 0.0, "a finite number >= 0"),
            ("k", math.isfinite(self.k) and self.k > 0.0, "a finite number > 0"),
            ("alpha", 0.0 < self.alpha < 1.0, "in (0, 1)"),
            ("gamma", 0.0 < self.gamma <= 1.0, "in (0, 1]"),
            ("horizon", self.horizon >= 1, "an integer >= 1"),
            ("budget", self.budget >= 0, "an integer >= 0"),
        )
        for name, ok, expected in checks:
            if not ok:
                raise StalmError(
                    f"search setting '{name}' must be {expected}, got {getattr(self, name)!r}"
                )
