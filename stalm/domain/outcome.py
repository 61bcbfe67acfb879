"""What T(s, a) returns: the next state and reward, or why the action was infeasible.

Failures are data. ``kind`` is one of :data:`FAILURE_KINDS`; ``blockers`` names the objects,
doors or static bodies in the way, so a user (and the Hcount heuristic) can see what blocked.
"""

from __future__ import annotations

from dataclasses import dataclass

from stalm.world.state import State

FAILURE_KINDS = (
    "precondition",
    "base_path_blocked",
    "no_ik",
    "arm_collision",
    "no_placement",
    "door_blocked",
    "inconsistent",
)
"""``inconsistent`` is replay's only: a saved action whose parameters do not fit the state
(a path not starting at the robot, a grasp away from the object, a placement the hand does not
reach), which a sampler never draws but a hand-edited plan file can hold."""


@dataclass(frozen=True)
class Infeasibility:
    """Why an action could not be executed: a kind, a sentence and the bodies in the way."""

    kind: str
    detail: str
    blockers: tuple[str, ...] = ()

    def __str__(self) -> str:
        if self.blockers:
            return f"{self.kind}: {self.detail} (blocked by {', '.join(self.blockers)})"
        return f"{self.kind}: {self.detail}"


@dataclass(frozen=True)
class Outcome:
    """Result of one transition: s', r, feasibility, the reason if infeasible, goal reached."""

    state: State
    reward: float
    feasible: bool
    failure: Infeasibility | None = None
    goal_reached: bool = False
