"""What a trial that ran out of time spent its time on, and the setting that would help.

A trial that times out says only 'timeout'; its phase times say where the budget went. The
phase that took the most (:meth:`PhaseTimes.phases`) and the run's settings tree decide the
advice (:func:`_setting_for`): a switch still off that narrows that phase
(``predicates.relevant_only`` first for the predicates, and for Fast Downward on a scene of
many objects), more processes for the predicates, fewer replies for a model or fewer
simulations for the tree; when nothing is left to switch, a longer ``--time-budget``. The
advice reads only the record: it is the same for a result reopened later.
"""

from __future__ import annotations

from dataclasses import dataclass

from stalm.settings.tree import RunSettings
from stalm.trial.result import PhaseTimes

MANY_OBJECTS = 30
"""From this many movable objects, relevant-only predicates are what a timeout asks for
first (P1-P6 have at most 16; the scale suite's scenes go to 120)."""

SHOWN_PHASES = {
    "setup": "set-up (building the scene)",
    "predicates": "predicates",
    "proposer": "the proposer",
    "concretize": "Concretize",
    "tree_search": "the tree search",
    "execution": "execution",
}


@dataclass(frozen=True)
class TimeoutAdvice:
    """Which phase dominated a timed-out trial, its share of the time, and what to try."""

    phase: str
    seconds: float
    share: float
    setting: str
    why: str

    def text(self) -> str:
        """The advice as one line (what ``stalm solve`` prints after a timeout)."""
        return (
            f"{SHOWN_PHASES.get(self.phase, self.phase)} took {self.seconds:.1f} s "
            f"({self.share:.0%} of the time); try {self.setting} ({self.why})"
        )


def timeout_advice(
    times: PhaseTimes, settings: RunSettings, objects: int, asks_model: bool | None = None
) -> TimeoutAdvice:
    """The advice for a trial that timed out after spending ``times``, run with ``settings``
    on a scene of ``objects`` movable objects; ``asks_model``: whether the planner asked a
    language model (:func:`stalm.planners.registry.asks_model`; None: read from ``settings``'s
    proposer section)."""
    phases = times.phases()
    phase = max(phases, key=lambda name: phases[name])
    seconds = phases[phase]
    total = times.total if times.total > 0 else sum(phases.values())
    share = seconds / total if total > 0 else 0.0
    setting, why = _setting_for(phase, settings, objects, asks_model)
    return TimeoutAdvice(phase, seconds, share, setting, why)


def _setting_for(
    phase: str, settings: RunSettings, objects: int, asks_model: bool | None
) -> tuple[str, str]:
    predicates, section = settings.predicates.for_objects(objects), settings.proposer
    symbolic = not (section.asks_model() if asks_model is None else asks_model)
    relevant = (
        "--set predicates.relevant_only=true",
        "occlusions only for the objects a plan must touch: a scene of many objects costs "
        "about what a small one does, and Fast Downward's task shrinks with it",
    )
    budget = ("a longer --time-budget", "no setting that narrows this phase is off")
    if phase == "predicates":
        if not predicates.relevant_only:
            return relevant
        if predicates.workers == 1:
            return (
                "--set predicates.workers=N",
                "N processes share a state's predicates; keep a core for each",
            )
        return budget
    if phase == "proposer" and symbolic:
        if not predicates.relevant_only and objects >= MANY_OBJECTS:
            return relevant
        if not section.needed_objects_only:
            return (
                "--set proposer.needed_objects_only=true",
                "Fast Downward gets only the objects an action on which can matter",
            )
        if not section.goal_relations_only:
            return (
                "--set proposer.goal_relations_only=true",
                "Fast Downward grounds relative placements only for the goal's relations",
            )
        if not predicates.relevant_only:
            return relevant
        return budget
    if phase == "proposer":
        return (
            f"fewer replies per query (--batch, now {settings.search.batch}) or a faster model",
            "the model's calls took the time",
        )
    if phase == "tree_search":
        return (
            "fewer simulations per step (--sims)",
            "the warm-started search took the time",
        )
    if not predicates.relevant_only and objects >= MANY_OBJECTS:
        return relevant
    return budget
