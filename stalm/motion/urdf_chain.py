"""A serial arm's kinematic chain read from a URDF: what forward kinematics and IK need.

The chain runs from a base link to a tool link (optionally on to a fixed tool frame, such as
the point between a gripper's fingers). Each revolute or continuous joint keeps its origin in
the previous joint's child link, its axis (any unit vector), its position limits and its
velocity limit; fixed joints are folded into the next origin, and those after the last moving
joint into the tool transform. Anything else between base and tool (a prismatic or floating
joint, a link that does not lead to the base) is refused with a message naming it, as is a
chain without 6 or 7 moving joints: what a serial arm is here.

PyBullet's body pose is its root link's *inertial* frame (``getBasePositionAndOrientation``
and ``resetBasePositionAndOrientation`` are about the centre of mass; only ``loadURDF``'s
``basePosition`` is the link frame), so the chain also keeps the root's inertial origin and
the fixed transform from the root to the base link: with them :meth:`UrdfChain.base_frame`
puts the base link where PyBullet's ``getLinkState(...)[4:6]`` reports it. The URDF is read
as XML, not through PyBullet, which re-expresses joint frames and axes in inertial frames.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stalm.errors import StalmError

MOVING_JOINTS = ("revolute", "continuous")
ARM_JOINT_COUNTS = (6, 7)
CONTINUOUS_SAMPLE_RANGE = (-math.pi, math.pi)
"""Where random configurations of a continuous joint are drawn (it has no limits)."""


def origin_transform(xyz: str | None, rpy: str | None) -> np.ndarray:
    """A URDF origin (xyz, rpy as fixed-axis roll, pitch, yaw) as a 4x4 transform."""
    return pose_transform(_floats(xyz or "0 0 0", 3), _floats(rpy or "0 0 0", 3))


def pose_transform(xyz: tuple[float, ...], rpy: tuple[float, ...]) -> np.ndarray:
    """A position and fixed-axis roll, pitch, yaw as a 4x4 transform (URDF's convention)."""
    x, y, z = (float(v) for v in xyz)
    roll, pitch, yaw = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    matrix = np.eye(4)
    matrix[:3, :3] = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    matrix[:3, 3] = (x, y, z)
    return matrix


def _floats(text: str, count: int) -> tuple[float, ...]:
    values = tuple(float(v) for v in text.split())
    if len(values) != count:
        raise ValueError(f"expected {count} numbers, got {text!r}")
    return values


@dataclass(frozen=True)
class ArmJoint:
    """One moving joint of the chain.

    ``origin`` is the joint frame in the previous moving joint's child link (for the first,
    in the base link), with every fixed joint in between folded in; the joint turns about
    ``axis`` (unit, in the joint frame). A continuous joint has infinite limits.
    """

    name: str
    kind: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    velocity: float | None


@dataclass(frozen=True)
class UrdfChain:
    """A serial arm of 6 or 7 moving joints between ``base_link`` and the tool frame."""

    urdf: Path
    base_link: str
    tool_link: str
    joints: tuple[ArmJoint, ...]
    tool: np.ndarray
    """From the last moving joint's child link to the tool frame (fixed joints, then the
    tool offset)."""
    root_link: str
    root_inertial: np.ndarray
    """The root link's inertial origin in its link frame: what PyBullet places."""
    root_to_base: np.ndarray
    """The base link in the root link's frame (fixed joints only)."""

    @property
    def dof(self) -> int:
        return len(self.joints)

    @property
    def frame_names(self) -> tuple[str, ...]:
        """The frames forward kinematics computes, in order: the base link, each moving
        joint's child link, and the tool frame (named after the tool link)."""
        return (self.base_link, *(joint.child for joint in self.joints), self.tool_link)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(joint.name for joint in self.joints)

    @property
    def origins(self) -> np.ndarray:
        return np.stack([joint.origin for joint in self.joints])

    @property
    def axes(self) -> np.ndarray:
        return np.stack([joint.axis for joint in self.joints])

    @property
    def lows(self) -> np.ndarray:
        return np.array([joint.lower for joint in self.joints])

    @property
    def highs(self) -> np.ndarray:
        return np.array([joint.upper for joint in self.joints])

    @property
    def velocity_limits(self) -> tuple[float | None, ...]:
        return tuple(joint.velocity for joint in self.joints)

    def sample_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Finite bounds to draw random configurations from: the limits, and
        :data:`CONTINUOUS_SAMPLE_RANGE` for continuous joints."""
        lows, highs = self.lows, self.highs
        lows[~np.isfinite(lows)] = CONTINUOUS_SAMPLE_RANGE[0]
        highs[~np.isfinite(highs)] = CONTINUOUS_SAMPLE_RANGE[1]
        return lows, highs

    def base_frame(self, body_pose: np.ndarray) -> np.ndarray:
        """The base link's world frame when PyBullet's body has ``body_pose`` (4x4) as
        ``getBasePositionAndOrientation`` reports it and ``resetBasePositionAndOrientation``
        sets it: the pose of the root's inertial frame, not of its link frame."""
        return body_pose @ np.linalg.inv(self.root_inertial) @ self.root_to_base

    def base_frame_as_loaded(self, load_pose: np.ndarray) -> np.ndarray:
        """The base link's world frame when ``loadURDF`` was given ``load_pose`` (4x4) as its
        base position and orientation, which it gives the root's link frame."""
        return load_pose @ self.root_to_base


def _origin_of(node: ElementTree.Element) -> np.ndarray:
    origin = node.find("origin")
    if origin is None:
        return np.eye(4)
    return origin_transform(origin.get("xyz"), origin.get("rpy"))


def _link_of(joint: ElementTree.Element, tag: str, where: str) -> str:
    node = joint.find(tag)
    if node is None or not node.get("link"):
        raise StalmError(f"{where}: joint {joint.get('name')!r} has no <{tag} link=...>")
    return str(node.get("link"))


def _moving_joint(node: ElementTree.Element, kind: str, origin: np.ndarray, where: str) -> ArmJoint:
    name = str(node.get("name"))
    axis_node = node.find("axis")
    axis = np.array(
        _floats(axis_node.get("xyz") or "1 0 0", 3) if axis_node is not None else (1.0, 0.0, 0.0)
    )
    norm = float(np.linalg.norm(axis))
    if norm < 1e-9:
        raise StalmError(f"{where}: joint {name!r} has a zero axis")
    limit = node.find("limit")
    velocity = None
    if limit is not None and limit.get("velocity") is not None:
        velocity = float(str(limit.get("velocity")))
    if kind == "continuous":
        lower, upper = -math.inf, math.inf
    else:
        if limit is None or limit.get("lower") is None or limit.get("upper") is None:
            raise StalmError(f"{where}: revolute joint {name!r} has no <limit lower= upper=>")
        lower, upper = float(str(limit.get("lower"))), float(str(limit.get("upper")))
        if not lower <= upper:
            raise StalmError(
                f"{where}: joint {name!r} has lower limit {lower} above upper limit {upper}"
            )
    return ArmJoint(
        name, kind, _link_of(node, "child", where), origin, axis / norm, lower, upper, velocity
    )


def read_chain(
    urdf: Path | str,
    base_link: str,
    tool_link: str,
    tool_offset: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None,
) -> UrdfChain:
    """The chain of ``urdf`` from ``base_link`` to ``tool_link``, then ``tool_offset``
    ((x, y, z), (roll, pitch, yaw)) in the tool link's frame; a StalmError naming the link or
    joint if it is not a serial arm of 6 or 7 revolute or continuous joints."""
    path = Path(urdf)
    where = f"URDF {path}"
    try:
        root = ElementTree.parse(path).getroot()
        links = {str(link.get("name")): link for link in root.findall("link")}
        parent_joint: dict[str, ElementTree.Element] = {}
        for joint in root.findall("joint"):
            parent_joint[_link_of(joint, "child", where)] = joint
        for name in (base_link, tool_link):
            if name not in links:
                raise StalmError(f"{where}: no link named {name!r}")
        path_up: list[ElementTree.Element] = []  # joints from the tool up to the base
        link = tool_link
        while link != base_link:
            if link not in parent_joint:
                raise StalmError(
                    f"{where}: link {tool_link!r} is not below base link {base_link!r} "
                    f"(going up from it ends at {link!r})"
                )
            joint = parent_joint[link]
            link = _link_of(joint, "parent", where)
            if link not in links:
                raise StalmError(
                    f"{where}: joint {joint.get('name')!r} names parent link {link!r}, "
                    "which the file does not declare"
                )
            path_up.append(joint)
        root_to_base = np.eye(4)
        link = base_link
        while link in parent_joint:  # from the base up to the root: fixed joints only
            joint = parent_joint[link]
            if joint.get("type") != "fixed":
                raise StalmError(
                    f"{where}: base link {base_link!r} moves with joint {joint.get('name')!r} "
                    f"({joint.get('type')}); an arm's base must be fixed to the root link"
                )
            root_to_base = _origin_of(joint) @ root_to_base
            link = _link_of(joint, "parent", where)
            if link not in links:
                raise StalmError(
                    f"{where}: joint {joint.get('name')!r} names parent link {link!r}, "
                    "which the file does not declare"
                )
        inertial = links[link].find("inertial")
        root_inertial = np.eye(4) if inertial is None else _origin_of(inertial)
        joints: list[ArmJoint] = []
        pending = np.eye(4)
        for joint in reversed(path_up):
            kind = str(joint.get("type"))
            if kind == "fixed":
                pending = pending @ _origin_of(joint)
            elif kind in MOVING_JOINTS:
                joints.append(_moving_joint(joint, kind, pending @ _origin_of(joint), where))
                pending = np.eye(4)
            else:
                raise StalmError(
                    f"{where}: joint {joint.get('name')!r} between {base_link!r} and "
                    f"{tool_link!r} is {kind}; an arm's chain takes revolute, continuous "
                    "and fixed joints"
                )
    except (ElementTree.ParseError, OSError, ValueError) as error:
        raise StalmError(f"{where}: cannot read the chain: {error}") from error
    if len(joints) not in ARM_JOINT_COUNTS:
        names = ", ".join(joint.name for joint in joints) or "none"
        raise StalmError(
            f"{where}: the chain from {base_link!r} to {tool_link!r} has {len(joints)} moving "
            f"joints ({names}); a serial arm here has 6 or 7"
        )
    tool = pending
    if tool_offset is not None:
        xyz, rpy = tool_offset
        tool = tool @ pose_transform(xyz, rpy)
    return UrdfChain(
        path, base_link, tool_link, tuple(joints), tool, link, root_inertial, root_to_base
    )
