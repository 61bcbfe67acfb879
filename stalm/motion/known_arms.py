"""The arms ``stalm bench ik --robot`` knows, as the chain each is read with: URDF (inside
``pybullet_data``), base link, tool link and the fixed tool offset from the tool link.

One table, so that robot description files can replace it in one place. The tool frames:
the Panda's is the URDF's own grasp target; the xArm6's is between its gripper's finger pads,
0.14 m along the gripper base's z (the fingers span 0.09-0.165 m there, measured from PyBullet's
bounding boxes with the gripper at zero, open); the iiwa's is its flange, 0.045 m along link 7's z
(the top of link 7's collision hull).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pybullet_data

from stalm.errors import StalmError
from stalm.motion.urdf_chain import UrdfChain, read_chain


@dataclass(frozen=True)
class KnownArm:
    urdf: str
    """Path inside ``pybullet_data``."""
    base_link: str
    tool_link: str
    tool_offset: tuple[tuple[float, float, float], tuple[float, float, float]] | None

    @property
    def path(self) -> Path:
        return Path(pybullet_data.getDataPath()) / self.urdf


KNOWN_ARMS = {
    "panda": KnownArm("franka_panda/panda.urdf", "panda_link0", "panda_grasptarget", None),
    "xarm6": KnownArm(
        "xarm/xarm6_with_gripper.urdf",
        "link_base",
        "xarm_gripper_base_link",
        ((0.0, 0.0, 0.14), (0.0, 0.0, 0.0)),
    ),
    "iiwa": KnownArm(
        "kuka_iiwa/model.urdf",
        "lbr_iiwa_link_0",
        "lbr_iiwa_link_7",
        ((0.0, 0.0, 0.045), (0.0, 0.0, 0.0)),
    ),
}


def known_arm(name: str) -> KnownArm:
    """The arm named ``name``, or a StalmError listing the names there are."""
    if name not in KNOWN_ARMS:
        raise StalmError(f"unknown robot {name!r}; known: {', '.join(KNOWN_ARMS)}")
    return KNOWN_ARMS[name]


def known_chain(name: str) -> UrdfChain:
    arm = known_arm(name)
    return read_chain(arm.path, arm.base_link, arm.tool_link, arm.tool_offset)
