"""Re-check a sampled action in a given state: every motion swept again against the scene.

Within the search, κ is checked when it is drawn and T then applies it without checking again.
A saved plan replayed in a fresh scene (``stalm replay``) goes through :func:`check_action`
first, so a plan file that does not fit the world is reported, never silently executed.
"""

from __future__ import annotations

from stalm.domain.outcome import Infeasibility
from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.motion.arm_motion import first_collision, interpolate_waypoints
from stalm.motion.base_motion import densify
from stalm.world.scene import Sim
from stalm.world.state import State


def _split(
    waypoints: tuple[tuple[float, ...], ...], at: tuple[float, ...]
) -> tuple[list[tuple[float, ...]], list[tuple[float, ...]]]:
    index = waypoints.index(at)
    return list(waypoints[: index + 1]), list(waypoints[index:])


def check_action(
    sim: Sim, state: State, action: Action, resolution: float = 0.05
) -> Infeasibility | None:
    """None if ``action``'s motions are collision-free in ``state``; else why not."""
    params = action.params
    sim.set_state(state)
    names = sim.bodies.name_of
    for pose in densify(params.base_path, resolution):
        sim.set_base_only(pose)
        hits = sim.robot_contacts()
        if hits:
            return Infeasibility(
                "base_path_blocked",
                "the saved base path collides",
                tuple(sorted(names(b) for b in hits)),
            )
    stand = params.base_path.corners[-1]
    sim.set_base_only(stand)
    if isinstance(params, PickParams):
        target = sim.bodies.objects[action.discrete.as_tuple()[1]]
        approach, lift = _split(params.arm_waypoints, params.grasp_conf)
        hits = first_collision(sim, stand, interpolate_waypoints(approach), {target})
        if not hits:
            sim.attach(params.grasp)
            hits = first_collision(sim, stand, interpolate_waypoints(lift))
            sim.attach(None)
    elif isinstance(params, PlaceParams):
        obj = action.discrete.as_tuple()[1]
        body = sim.bodies.objects[obj]
        lower, retreat = _split(params.arm_waypoints, params.place_conf)
        hits = first_collision(sim, stand, interpolate_waypoints(lower))
        if not hits:
            sim.attach(None)
            sim.place_object(obj, params.placement)
            hits = sim.contacts_of([body], (sim.bodies.base, sim.bodies.arm))
            if not hits:
                hits = first_collision(sim, stand, interpolate_waypoints(retreat), {body})
    else:
        assert isinstance(params, OpenParams)
        door = sim.bodies.doors[action.discrete.as_tuple()[1]]
        hits = first_collision(
            sim, stand, interpolate_waypoints(list(params.arm_waypoints)), {door}
        )
    if hits:
        return Infeasibility(
            "arm_collision",
            f"the saved motion of {action.discrete} collides",
            tuple(sorted(names(b) for b in hits)),
        )
    return None
