"""Actions with their continuous parameters to and from JSON, so plans can be saved, replayed
in a fresh scene and animated."""

from __future__ import annotations

from typing import Any

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.errors import StalmError
from stalm.motion.base_motion import BasePath
from stalm.world.state import Grasp, ObjectPose


def discrete_to_json(action: DiscreteAction) -> list[str]:
    return list(action.as_tuple())


def discrete_from_json(data: list[str]) -> DiscreteAction:
    op, *args = data
    if op == "pick" and len(args) == 1:
        return Pick(args[0])
    if op == "place" and len(args) == 3:
        return Place(args[0], args[1], args[2])  # type: ignore[arg-type]
    if op == "open" and len(args) == 1:
        return Open(args[0])
    raise StalmError(f"not a discrete action: {data!r}")


def action_to_json(action: Action) -> dict[str, Any]:
    params = action.params
    data: dict[str, Any] = {
        "action": discrete_to_json(action.discrete),
        "base_path": [list(c) for c in params.base_path.corners],
        "arm_waypoints": [list(c) for c in params.arm_waypoints],
    }
    if isinstance(params, PickParams):
        data.update(
            pitch=params.pitch,
            yaw=params.yaw,
            grasp={
                "position": list(params.grasp.position),
                "orientation": list(params.grasp.orientation),
            },
            grasp_conf=list(params.grasp_conf),
        )
    elif isinstance(params, PlaceParams):
        p = params.placement
        data.update(placement=[p.x, p.y, p.z, p.yaw], place_conf=list(params.place_conf))
    else:
        data.update(handle_conf=list(params.handle_conf))
    return data


def action_from_json(data: dict[str, Any]) -> Action:
    """The inverse of :func:`action_to_json`; a malformed entry raises :class:`StalmError`."""
    try:
        discrete = discrete_from_json(data["action"])
        path = BasePath(tuple(tuple(float(v) for v in c) for c in data["base_path"]))  # type: ignore[misc]
        waypoints = tuple(tuple(float(v) for v in c) for c in data["arm_waypoints"])
        if isinstance(discrete, Pick):
            grasp = Grasp.make(
                discrete.obj, tuple(data["grasp"]["position"]), tuple(data["grasp"]["orientation"])
            )
            params: PickParams | PlaceParams | OpenParams = PickParams(
                path,
                float(data["pitch"]),
                float(data["yaw"]),
                grasp,
                tuple(float(v) for v in data["grasp_conf"]),
                waypoints,
            )
        elif isinstance(discrete, Place):
            params = PlaceParams(
                path,
                ObjectPose.make(*data["placement"]),
                tuple(float(v) for v in data["place_conf"]),
                waypoints,
            )
        else:
            params = OpenParams(path, tuple(float(v) for v in data["handle_conf"]), waypoints)
    except (KeyError, TypeError, ValueError, IndexError) as error:
        raise StalmError(f"malformed action in plan: {error!r}") from None
    return Action(discrete, params)
