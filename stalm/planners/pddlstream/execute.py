"""Executing a plan over real objects in the domain, and turning failures into knowledge.

A plan step names its sampled values; the action is built from them (base path planned now,
from where the robot really stands, with the real obstacles; the arm motion the stream
planned), checked as ``stalm replay`` checks it (:func:`stalm.domain.verify.check_action`),
then applied with :meth:`Domain.step`. When a step fails, what blocked it becomes a fact:
an object in the way at its current pose gives ``Collides(m, o, p)``, a closed door
``Crosses(m, d)``; with nothing to blame the motion is retired. Either way that motion is not
offered again in that situation, and the planner re-plans from the state reached.
"""

from __future__ import annotations

from dataclasses import dataclass

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.domain.outcome import Infeasibility
from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.domain.verify import check_action
from stalm.errors import StalmError
from stalm.planners.pddlstream.knowledge import Knowledge
from stalm.planners.pddlstream.pddl_text import Fact
from stalm.world.state import State


@dataclass(frozen=True)
class StepFailure:
    """Why a plan step could not be executed and the facts learned from it."""

    step: tuple[str, ...]
    failure: Infeasibility
    learned: tuple[Fact, ...]
    retired: bool


def build_action(
    domain: Domain, knowledge: Knowledge, state: State, step: tuple[str, ...]
) -> Action | Infeasibility:
    """The executable action of a plan step in ``state``, or why it is not executable."""
    operator, *args = step
    motion = knowledge.motions[step[-1]]  # a step's last argument is its motion
    path = domain.samplers.base_path(state, motion.stand)
    if isinstance(path, Infeasibility):
        return path
    action: Action
    if operator == "pick":
        obj, _, grasp_name, _ = args
        grasp = knowledge.grasps[grasp_name]
        params = PickParams(
            path, grasp.pitch, grasp.yaw, grasp.grasp, motion.key_conf, motion.waypoints
        )
        action = Action(Pick(obj), params)
    elif operator == "place":
        obj, pose_name, _, _ = args
        pose = knowledge.poses[pose_name]
        region = knowledge.geometry.spec.region(pose.region)
        place = Place(obj, "on", region.name)
        action = Action(place, PlaceParams(path, pose.pose, motion.key_conf, motion.waypoints))
    elif operator == "open":
        action = Action(Open(args[0]), OpenParams(path, motion.key_conf, motion.waypoints))
    else:
        raise StalmError(f"Fast Downward returned an unknown operator '{operator}'")
    why = domain.precondition_failure(state, action.discrete)
    if why is not None:
        return Infeasibility("precondition", why)
    failure = check_action(domain.sim, state, action)
    return action if failure is None else failure


def learn_from(
    knowledge: Knowledge, state: State, step: tuple[str, ...], failure: Infeasibility
) -> StepFailure:
    """Record what blocked ``step`` in ``state`` so the next search avoids it."""
    motion = step[-1]
    learned: list[Fact] = []
    doors = {d.name for d in knowledge.geometry.spec.doors}
    for blocker in failure.blockers:
        fact: Fact | None = None
        if blocker in doors and not state.is_open(blocker):
            fact = ("Crosses", motion, blocker)
        elif state.has_pose(blocker):
            pose = knowledge.pose_name(blocker, state.pose(blocker))
            if pose is not None:
                fact = ("Collides", motion, blocker, pose)
        if fact is not None and fact not in knowledge.facts:
            knowledge.facts.add(fact)
            learned.append(fact)
    retired = not learned
    if retired:
        knowledge.retire(motion)
    return StepFailure(step, failure, tuple(learned), retired)
