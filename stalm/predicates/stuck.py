"""Objects that no action can ever move: a problem-file check beyond the scene's collisions.

An object wider than the gripper opens across every closing direction, one whose every
sampled pick is statically infeasible (no IK, or a motion through the static scene), or one
which can be picked but put down on no region, never moves whatever the planner does.
``stalm problems --file`` warns about each one (a goal that needs it moved cannot be
reached), sampling as the predicates do, with their extra draws before giving up
(:class:`~stalm.predicates.samples.PredicateSettings`). ``stalm solve`` asks only about the
objects its goal needs moved (:func:`goal_unreachable`) and, when a goal atom can then never
come true (:func:`unreachable_goal`), says so up front and names it as the run's termination.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping

from stalm.motion.base_motion import BasePlanner
from stalm.motion.manipulation import PARKED
from stalm.predicates.samples import MotionSamples, PredicateSettings
from stalm.world.grip_widths import too_wide
from stalm.world.problem import Problem
from stalm.world.relations import at_position
from stalm.world.scene import Sim

CheckProgress = Callable[[int, int], None]
"""Hears ``done`` of ``total`` objects checked (a scene of 500 objects takes minutes)."""


def stuck_objects(
    problem: Problem,
    sim: Sim,
    base_planner: BasePlanner,
    settings: PredicateSettings | None = None,
    *,
    names: Collection[str] | None = None,
    progress: CheckProgress | None = None,
) -> dict[str, str]:
    """Each object of the initial state (of ``names`` only, if given) that can never move,
    with why (in words); ``progress`` hears each object checked."""
    samples = MotionSamples(problem.spec, sim, base_planner, settings or PredicateSettings())
    state = problem.initial_state
    poses = [(name, pose) for name, pose in state.poses if names is None or name in names]
    stuck: dict[str, str] = {}
    for done, (name, pose) in enumerate(poses):
        if progress is not None:
            progress(done, len(poses))
        sim.set_state(state)
        wide = too_wide(problem.spec.object(name), sim.robot.gripper.opening)
        if wide is not None:
            stuck[name] = wide
            continue
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
    if progress is not None:
        progress(len(poses), len(poses))
    sim.set_state(state)
    return stuck


def _open_atoms(problem: Problem) -> list[tuple[int, tuple[str, ...]]]:
    """(index, the objects whose moving could make it true) of each goal atom that the
    initial state does not satisfy."""
    spec, state = problem.spec, problem.initial_state
    return [
        (index, (atom.obj,) if atom.direction == "on" else (atom.obj, atom.ref))
        for index, atom in enumerate(problem.goal)
        if not at_position(spec, state, atom.obj, atom.direction, atom.ref)
    ]


def unreachable_goal(problem: Problem, stuck: Mapping[str, str]) -> str | None:
    """Why the goal can never be reached when the objects of ``stuck`` never move (one
    line, naming the first goal atom none of whose objects can move), or None."""
    for index, movers in _open_atoms(problem):
        if all(name in stuck for name in movers):
            atom = problem.goal[index]
            why = "; ".join(f"'{name}' can never be moved: {stuck[name]}" for name in movers)
            return f"goal[{index}] ('{atom.obj}' {atom.direction} '{atom.ref}'): {why}"
    return None


def goal_unreachable(problem: Problem, settings: PredicateSettings | None = None) -> str | None:
    """:func:`unreachable_goal` with only the objects the goal needs moved checked (a
    relative atom's reference only when its subject cannot move), in a scene of its own:
    what ``stalm solve`` asks before its clock starts."""
    atoms = _open_atoms(problem)
    if not atoms:
        return None
    with Sim(problem.spec) as sim:
        base_planner = BasePlanner(sim)
        subjects = {movers[0] for _, movers in atoms}
        stuck = stuck_objects(problem, sim, base_planner, settings, names=subjects)
        # a reference matters only where its subject cannot move
        references = {m[1] for _, m in atoms if len(m) > 1 and m[0] in stuck} - subjects
        if references:
            stuck |= stuck_objects(problem, sim, base_planner, settings, names=references)
    return unreachable_goal(problem, stuck)
