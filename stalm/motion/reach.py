"""The arm's waypoints for reaching a gripper pose and for leaving it.

PICK, PLACE and OPEN (``stalm.domain``) and the occlusion predicates (``stalm.predicates``)
must plan the very same arm motions, so both build them here: reaching raises the lift with
the arm folded, moves to a pose offset from the target (backed off along the approach axis or
raised above it), then to the target; leaving goes to an offset pose and folds back.
"""

from __future__ import annotations

from stalm.geometry.transforms import Pose3
from stalm.motion.grasps import offset_pose
from stalm.motion.ik import IKSolution, solve_ik_from
from stalm.world.robot import fold, unfold
from stalm.world.scene import Sim

Conf = tuple[float, ...]
SE2 = tuple[float, float, float]


def solution_conf(solution: IKSolution) -> Conf:
    """Lift then arm joints: the vector arm motion interpolates."""
    return (solution.lift, *solution.arm)


def offset_conf(
    sim: Sim,
    base: SE2,
    target: Pose3,
    solution: IKSolution,
    backoff: float = 0.0,
    raise_by: float = 0.0,
) -> Conf:
    """The configuration with the gripper backed off along its approach axis and/or raised,
    by IK seeded at ``solution``; the target configuration itself when IK cannot reach it."""
    near = solve_ik_from(sim, base, offset_pose(target, backoff, raise_by), solution)
    return solution_conf(near if near is not None else solution)


def reach_waypoints(
    sim: Sim,
    base: SE2,
    target: Pose3,
    solution: IKSolution,
    backoff: float = 0.0,
    raise_by: float = 0.0,
) -> list[Conf]:
    """Folded arm at the target's lift height, the offset pose, then the target."""
    goal = solution_conf(solution)
    return [
        *unfold(goal, sim.robot.carry_conf),
        offset_conf(sim, base, target, solution, backoff, raise_by),
        goal,
    ]


def leave_waypoints(
    sim: Sim,
    base: SE2,
    target: Pose3,
    solution: IKSolution,
    backoff: float = 0.0,
    raise_by: float = 0.0,
) -> list[Conf]:
    """The target, the offset pose, then the arm folded back to the driving configuration."""
    start = solution_conf(solution)
    return [
        start,
        offset_conf(sim, base, target, solution, backoff, raise_by),
        *fold(start, sim.robot.carry_conf),
    ]
