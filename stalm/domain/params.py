"""Continuous parameters κ of each operator (Table 1), and a full action α(δ, κ).

κ records everything needed to execute or animate the action: the base path, the sampled
gripper orientation or placement, the IK solution and the arm's joint-space waypoints (the
dense motion is their linear interpolation). All parts are tuples so κ is hashable and can
key a continuous node's children.
"""

from __future__ import annotations

from dataclasses import dataclass

from stalm.domain.actions import DiscreteAction
from stalm.motion.base_motion import BasePath
from stalm.world.state import Grasp, ObjectPose

Conf = tuple[float, ...]


@dataclass(frozen=True)
class PickParams:
    """PICK: base path, gripper pitch and yaw (relative to the standing pose), and arm motion."""

    base_path: BasePath
    pitch: float
    yaw: float
    grasp: Grasp
    grasp_conf: Conf
    arm_waypoints: tuple[Conf, ...]


@dataclass(frozen=True)
class PlaceParams:
    """PLACE: base path, the sampled placement (x, y) with the kept orientation, arm motion."""

    base_path: BasePath
    placement: ObjectPose
    place_conf: Conf
    arm_waypoints: tuple[Conf, ...]


@dataclass(frozen=True)
class OpenParams:
    """OPEN: base path to the door's standing pose and the arm motion to its fixed handle grasp."""

    base_path: BasePath
    handle_conf: Conf
    arm_waypoints: tuple[Conf, ...]


ContinuousParams = PickParams | PlaceParams | OpenParams


@dataclass(frozen=True)
class Action:
    """α(δ, κ): a discrete action with its continuous parameters."""

    discrete: DiscreteAction
    params: ContinuousParams

    def __str__(self) -> str:
        return str(self.discrete)
