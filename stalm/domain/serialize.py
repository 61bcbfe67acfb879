"""Actions with their continuous parameters to and from JSON, so plans can be saved, replayed
in a fresh scene and animated."""

from __future__ import annotations

import math
from typing import Any

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.errors import StalmError
from stalm.motion.base_motion import BasePath
from stalm.world.robot import CARRY_CONF
from stalm.world.state import Grasp, ObjectPose


def discrete_to_json(action: DiscreteAction) -> list[str]:
    return list(action.as_tuple())


def discrete_from_json(data: list[str]) -> DiscreteAction:
    if not isinstance(data, list) or not data or not all(isinstance(x, str) for x in data):
        raise StalmError(f"not a discrete action: {data!r:.80}")
    op, *args = data
    if op == "pick" and len(args) == 1:
        return Pick(args[0])
    if op == "place" and len(args) == 3:
        return Place(args[0], args[1], args[2])  # type: ignore[arg-type]
    if op == "open" and len(args) == 1:
        return Open(args[0])
    raise StalmError(f"not a discrete action: {data!r:.80}")


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


CONF_LENGTH = len(CARRY_CONF)
"""The Panda's configuration: the lift height and its seven arm joints."""


def _numbers(value: Any, length: int, what: str) -> tuple[float, ...]:
    """``value`` as ``length`` finite floats, or a StalmError naming ``what``.

    A plan file is not ours: NaN or infinity would pass every comparison in the collision
    checks (NaN < x is false) and could make a forged plan look feasible, so they are refused.
    """
    if not isinstance(value, list | tuple) or len(value) != length:
        raise StalmError(f"'{what}' must be a list of {length} numbers, got {value!r:.60}")
    numbers = []
    for item in value:
        if isinstance(item, bool) or not isinstance(item, int | float):
            raise StalmError(f"'{what}' holds {item!r:.20}, not a number")
        if not math.isfinite(item):
            raise StalmError(f"'{what}' holds {item}: numbers must be finite")
        numbers.append(float(item))
    return tuple(numbers)


def _number(value: Any, what: str) -> float:
    return _numbers([value], 1, what)[0]


def _sequence(value: Any, length: int, what: str) -> tuple[tuple[float, ...], ...]:
    if not isinstance(value, list | tuple) or not value:
        raise StalmError(f"'{what}' must be a non-empty list, got {value!r:.60}")
    return tuple(_numbers(item, length, f"{what}[{i}]") for i, item in enumerate(value))


def action_from_json(data: dict[str, Any], conf_length: int = CONF_LENGTH) -> Action:
    """The inverse of :func:`action_to_json`; a malformed entry raises :class:`StalmError`.
    A configuration holds ``conf_length`` numbers (the lift and the robot's joints).

    Every number must be finite and every list the right length, and the key configuration
    of a pick or place must be one of its waypoints (the motion is split there).
    """
    if not isinstance(data, dict):
        raise StalmError(f"not an action (a JSON object): {data!r:.60}")
    try:
        discrete = discrete_from_json(data["action"])
        path = BasePath(_sequence(data["base_path"], 3, "base_path"))  # type: ignore[arg-type]
        waypoints = _sequence(data["arm_waypoints"], conf_length, "arm_waypoints")
        params: PickParams | PlaceParams | OpenParams
        if isinstance(discrete, Pick):
            grasp = data["grasp"]
            if not isinstance(grasp, dict):
                raise StalmError("'grasp' must be an object with 'position' and 'orientation'")
            grasp_conf = _numbers(data["grasp_conf"], conf_length, "grasp_conf")
            _key_conf_in(grasp_conf, waypoints, "grasp_conf")
            params = PickParams(
                path,
                _number(data["pitch"], "pitch"),
                _number(data["yaw"], "yaw"),
                Grasp.make(
                    discrete.obj,
                    _numbers(grasp["position"], 3, "grasp.position"),
                    _numbers(grasp["orientation"], 4, "grasp.orientation"),
                ),
                grasp_conf,
                waypoints,
            )
        elif isinstance(discrete, Place):
            place_conf = _numbers(data["place_conf"], conf_length, "place_conf")
            _key_conf_in(place_conf, waypoints, "place_conf")
            params = PlaceParams(
                path,
                ObjectPose.make(*_numbers(data["placement"], 4, "placement")),
                place_conf,
                waypoints,
            )
        else:
            handle_conf = _numbers(data["handle_conf"], conf_length, "handle_conf")
            params = OpenParams(path, handle_conf, waypoints)
    except KeyError as error:
        raise StalmError(f"malformed action in plan: no {error}") from None
    except (TypeError, ValueError, IndexError) as error:
        raise StalmError(f"malformed action in plan: {error!r}") from None
    return Action(discrete, params)


def _key_conf_in(
    conf: tuple[float, ...], waypoints: tuple[tuple[float, ...], ...], what: str
) -> None:
    if conf not in waypoints:
        raise StalmError(f"'{what}' is not one of the arm waypoints")
