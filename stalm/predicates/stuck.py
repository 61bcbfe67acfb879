"""Objects that no action can ever move: a problem-file check beyond the scene's collisions.

An object whose every sampled pick is statically infeasible (no IK, or a motion through the
static scene), or which can be picked but put down on no region, never moves whatever the
planner does. ``stalm problems --file`` warns about each one (a goal that needs it moved
cannot be reached), sampling as the predicates do, with their extra draws before giving up
(:class:`~stalm.predicates.samples.PredicateSettings`).
"""

from __future__ import annotations

from stalm.motion.base_motion import BasePlanner
from stalm.motion.manipulation import PARKED
from stalm.predicates.samples import MotionSamples, PredicateSettings
from stalm.world.problem import Problem
from stalm.world.scene import Sim


def stuck_objects(
    problem: Problem, sim: Sim, base_planner: BasePlanner, settings: PredicateSettings | None = None
) -> dict[str, str]:
    """Each object of the initial state that can never move, with why (in words)."""
    samples = MotionSamples(problem.spec, sim, base_planner, settings or PredicateSettings())
    state = problem.initial_state
    stuck: dict[str, str] = {}
    for name, pose in state.poses:
        sim.set_state(state)
        record = samples.pick_record(name, pose)
        if record.grasp is None:
            stuck[name] = "no sampled pick reaches it without touching the static scene"
            continue
        sim.place_object(name, PARKED)  # in the hand, it stands nowhere
        regions = problem.spec.regions
        if not any(
            samples.placements(name, record.grasp, record.yaw_offset, r, persist=True)
            for r in regions
        ):
            stuck[name] = "it can be picked but no sampled placement on any region is feasible"
    sim.set_state(state)
    return stuck
