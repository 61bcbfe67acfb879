"""The registry's rows as data: each planner's name, what it is, whether it asks a language
model, and its N_budget.

This is the one place a planner's default N_budget is written. The registry
(:mod:`stalm.planners.registry`) pairs each row with its planner's builder and fills
``search.sims`` from the row before it builds; a planner built by hand
(``StalmPlanner(proposer)``, ``LlmMctsPlanner(proposer)``) reads its row here. This module
imports no planner, so the planner modules and the registry above them can both read it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from stalm.settings.tree import RunSettings


@dataclass(frozen=True)
class PlannerRow:
    """One planner: its name, what it is, whether it needs a language model, its N_budget."""

    name: str
    description: str
    uses_llm: bool
    sims: int | None = None
    """N_budget when ``search.sims`` is None: STaLM's 30 (Appendix B), the baselines' 35
    (§4.2); None: the planner runs no tree search."""

    def settings_for(self, settings: RunSettings) -> RunSettings:
        """``settings`` as this row runs them: its N_budget where ``search.sims`` is None."""
        if self.sims is None or settings.search.sims is not None:
            return settings
        return replace(settings, search=replace(settings.search, sims=self.sims))


ROWS: tuple[PlannerRow, ...] = (
    PlannerRow(
        "stalm",
        "STaLM: task plans from the proposer, Concretize, warm-started hybrid UCT (N_budget 30)",
        True,
        sims=30,
    ),
    PlannerRow(
        "stalm-no-uct",
        "STaLM without UCT (Table 3): Concretize only, then the next action of the best plan",
        True,
        sims=30,
    ),
    PlannerRow(
        "uct", "Hybrid UCT with random rollouts and no guidance (N_budget 35)", False, sims=35
    ),
    PlannerRow(
        "uct-hcount",
        "UCT whose leaf value is Appendix C's Hcount heuristic (N_budget 35)",
        False,
        sims=35,
    ),
    PlannerRow(
        "ep-saycan",
        "SayCan with an empirical policy: 5 replies to a history-only prompt times precondition "
        "affordance, no search",
        True,
    ),
    PlannerRow(
        "iterative-replanning",
        "One plan per query; on failure re-ask with up to two failed plans and the failure "
        "(5 attempts, then one step)",
        True,
    ),
    PlannerRow(
        "llm-mcts",
        "MCTS with PUCT whose prior is the first actions of 5 replies at every new node "
        "(N_budget 35)",
        True,
        sims=35,
    ),
    PlannerRow(
        "pddlstream-adaptive",
        "PDDLStream's adaptive algorithm: Fast Downward over sampled values as PDDL objects, "
        "failed samples fed back",
        False,
    ),
)
"""Every planner, in the order the README's table lists them."""


def planner_rows() -> dict[str, PlannerRow]:
    """Every row by planner name."""
    return {row.name: row for row in ROWS}
