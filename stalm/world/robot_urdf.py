"""What a robot's URDF says, read through PyBullet as the planner's simulator will read it.

A robot file is checked against its URDF here: the base and tool links exist, the path
between them is a serial arm of 6 or 7 revolute joints, the limits are complete, the carry
configuration lies inside them and the gripper opens no wider than its fingers' collision
geometry allows. PyBullet rather than a URDF parser reads the file, so the chain, limits and
collision shapes are the ones the simulator uses (a URDF PyBullet reads differently than a
parser would is reported as PyBullet reads it). Every query opens a DIRECT client of its own
and closes it, so nothing here touches a scene's client.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p

from stalm.errors import StalmError
from stalm.geometry.transforms import matrix_from_quat, pose_matrix
from stalm.world.robot_description import ChainJoint, Robot, RobotSpec

ARM_JOINTS = (6, 7)
"""Revolute joints a supported arm has between its base and tool links."""
OPENING_TOLERANCE = 0.0005
"""How much wider (m) a file's gripper opening may be than the gap measured in PyBullet
(the measure's own rounding; a real mismatch is millimetres)."""
_KINDS = {p.JOINT_REVOLUTE: "revolute", p.JOINT_PRISMATIC: "prismatic", p.JOINT_FIXED: "fixed"}
_NAMES_SHOWN = 12


@dataclass(frozen=True)
class UrdfBody:
    """A URDF loaded alone (fixed base at the origin) in a DIRECT client of its own."""

    client: int
    body: int
    links: dict[str, int]
    """Link name to PyBullet's link index (the root link is -1)."""

    def joint_info(self, index: int) -> tuple[Any, ...]:
        return tuple(p.getJointInfo(self.body, index, physicsClientId=self.client))

    def set_joints(self, joints: Sequence[ChainJoint], values: Sequence[float]) -> None:
        for joint, value in zip(joints, values, strict=True):
            p.resetJointState(self.body, joint.index, value, physicsClientId=self.client)

    def link_frame(self, link: int) -> np.ndarray:
        """The 4x4 pose of a link's URDF frame (not its inertial frame) in the world."""
        c = self.client
        if link >= 0:
            state = p.getLinkState(self.body, link, computeForwardKinematics=1, physicsClientId=c)
            return pose_matrix((state[4], state[5]))
        com = pose_matrix(p.getBasePositionAndOrientation(self.body, physicsClientId=c))
        return com @ np.linalg.inv(self.inertial_offset(-1))

    def inertial_offset(self, link: int) -> np.ndarray:
        """The link's inertial frame in its URDF frame (PyBullet keeps shapes in the former)."""
        info = p.getDynamicsInfo(self.body, link, physicsClientId=self.client)
        return pose_matrix((info[3], info[4]))


@contextmanager
def urdf_body(urdf: Path, source: str = "urdf") -> Iterator[UrdfBody]:
    """Load ``urdf`` in a new DIRECT client; a StalmError naming ``source`` if PyBullet cannot."""
    if not urdf.is_file():
        raise StalmError(f"{source}: no URDF file {str(urdf)!r}")
    client = p.connect(p.DIRECT)
    try:
        try:
            body = p.loadURDF(str(urdf), useFixedBase=True, physicsClientId=client)
        except p.error:
            raise StalmError(f"{source}: PyBullet cannot load the URDF {str(urdf)!r}") from None
        links = {p.getBodyInfo(body, physicsClientId=client)[0].decode(): -1}
        for index in range(p.getNumJoints(body, physicsClientId=client)):
            info = p.getJointInfo(body, index, physicsClientId=client)
            links[info[12].decode()] = index
        yield UrdfBody(client, body, links)
    finally:
        p.disconnect(client)


def _named(names: Sequence[str]) -> str:
    shown = ", ".join(list(names)[:_NAMES_SHOWN])
    return shown + (", ..." if len(names) > _NAMES_SHOWN else "")


def link_index(loaded: UrdfBody, name: str, field: str) -> int:
    """The index of the link ``name``; a StalmError naming ``field`` if the URDF has none."""
    if name not in loaded.links:
        raise StalmError(
            f"{field}: no link {name!r} in the URDF (links: {_named(list(loaded.links))})"
        )
    return loaded.links[name]


def read_chain(loaded: UrdfBody, base_link: str, tool_link: str) -> tuple[ChainJoint, ...]:
    """The joints from ``base_link`` down to ``tool_link``, base first."""
    base = link_index(loaded, base_link, "base_link")
    link = link_index(loaded, tool_link, "tool_link")
    joints: list[ChainJoint] = []
    while link != base:
        if link == -1:
            raise StalmError(f"tool_link: {tool_link!r} is not below base_link {base_link!r}")
        info = loaded.joint_info(link)
        kind = _KINDS.get(int(info[2]), "other")
        joints.append(
            ChainJoint(
                name=info[1].decode(),
                kind=kind,
                index=link,
                child_link=info[12].decode(),
                lower=float(info[8]),
                upper=float(info[9]),
                velocity=float(info[11]),
            )
        )
        link = int(info[16])
    return tuple(reversed(joints))


def _check_chain(chain: Sequence[ChainJoint], spec: RobotSpec) -> tuple[ChainJoint, ...]:
    moving = tuple(joint for joint in chain if joint.kind != "fixed")
    for joint in moving:
        if joint.kind != "revolute":
            raise StalmError(
                f"tool_link: joint {joint.name!r} between base_link and tool_link is "
                f"{joint.kind}; an arm's chain is 6 or 7 revolute joints"
            )
    if len(moving) not in ARM_JOINTS:
        raise StalmError(
            f"tool_link: the chain from {spec.base_link!r} to {spec.tool_link!r} has "
            f"{len(moving)} revolute joints; an arm has 6 or 7"
        )
    return moving


def _sized(field: str, values: Sequence[object] | None, count: int) -> None:
    if values is not None and len(values) != count:
        raise StalmError(f"{field}: {len(values)} values for a chain of {count} joints")


def _limits(spec: RobotSpec, moving: Sequence[ChainJoint]) -> tuple[tuple[float, float], ...]:
    if spec.joint_limits is not None:
        return spec.joint_limits
    for joint in moving:
        if not joint.lower < joint.upper:  # PyBullet reports a continuous joint as 0 .. -1
            raise StalmError(
                f"joint_limits: joint {joint.name!r} has no limits in the URDF; give joint_limits"
            )
    return tuple((joint.lower, joint.upper) for joint in moving)


def _velocities(spec: RobotSpec, moving: Sequence[ChainJoint]) -> tuple[float, ...]:
    if spec.velocity_limits is not None:
        return spec.velocity_limits
    for joint in moving:
        if not (math.isfinite(joint.velocity) and joint.velocity > 0):
            raise StalmError(
                f"velocity_limits: joint {joint.name!r} has no velocity limit in the URDF; "
                "give velocity_limits"
            )
    return tuple(joint.velocity for joint in moving)


def _check_carry(
    spec: RobotSpec, moving: Sequence[ChainJoint], limits: Sequence[tuple[float, float]]
) -> None:
    for field, conf in (("carry", spec.carry), ("ready", spec.ready)):
        if conf is None:
            continue
        _sized(field, conf, len(moving))
        for index, (value, joint, (low, high)) in enumerate(zip(conf, moving, limits, strict=True)):
            if not low <= value <= high:
                raise StalmError(
                    f"{field}[{index}]: {value} is outside joint {joint.name!r}'s limits "
                    f"[{low}, {high}]"
                )


def finger_gap(loaded: UrdfBody, spec: RobotSpec) -> float:
    """The gap (m) between the two finger links' collision geometry with the fingers open."""
    assert spec.gripper is not None
    gripper = spec.gripper
    chain = {joint.name for joint in read_chain(loaded, spec.base_link, spec.tool_link)}
    for name, value in gripper.finger_joints.items():
        if name in chain:
            raise StalmError(f"gripper.finger_joints: {name!r} is a joint of the arm's chain")
        index = next((i for i, n in _joint_names(loaded).items() if n == name), None)
        if index is None:
            raise StalmError(f"gripper.finger_joints: no joint {name!r} in the URDF")
        info = loaded.joint_info(index)
        low, high = float(info[8]), float(info[9])
        if low < high and not low <= value <= high:
            raise StalmError(
                f"gripper.finger_joints.{name}: {value} is outside the joint's limits "
                f"[{low}, {high}]"
            )
        p.resetJointState(loaded.body, index, value, physicsClientId=loaded.client)
    left, right = (
        link_index(loaded, name, f"gripper.finger_links[{i}]")
        for i, name in enumerate(gripper.finger_links)
    )
    points = p.getClosestPoints(
        loaded.body, loaded.body, 1.0, left, right, physicsClientId=loaded.client
    )
    if not points:
        raise StalmError(
            "gripper.finger_links: the two links have no collision geometry a metre apart"
        )
    return float(min(point[8] for point in points))


def _joint_names(loaded: UrdfBody) -> dict[int, str]:
    return {
        index: loaded.joint_info(index)[1].decode()
        for index in range(p.getNumJoints(loaded.body, physicsClientId=loaded.client))
    }


def collision_files(loaded: UrdfBody) -> list[Path]:
    """Every mesh file a link of the body collides with, sorted, each once."""
    files: set[Path] = set()
    for link in loaded.links.values():
        for shape in p.getCollisionShapeData(loaded.body, link, physicsClientId=loaded.client):
            path = Path(shape[4].decode())
            if shape[2] == p.GEOM_MESH and path.is_file():  # a URDF cylinder: "unknown_file"
                files.add(path)
    return sorted(files)


def content_hash(urdf: Path, meshes: Sequence[Path]) -> str:
    """SHA-256 over the URDF's bytes and each collision mesh's: a change to any shape a
    sphere set was fitted to changes it."""
    digest = hashlib.sha256(urdf.read_bytes())
    for mesh in meshes:
        digest.update(mesh.name.encode())
        digest.update(mesh.read_bytes())
    return digest.hexdigest()


def check_against_urdf(spec: RobotSpec, source: str, urdf: Path) -> Robot:
    """The robot ``spec`` describes, checked against ``urdf``; a StalmError naming ``source``
    and the field at fault otherwise."""
    try:
        with urdf_body(urdf) as loaded:
            chain = read_chain(loaded, spec.base_link, spec.tool_link)
            moving = _check_chain(chain, spec)
            for field in ("carry", "joint_limits", "velocity_limits", "acceleration_limits"):
                _sized(field, getattr(spec, field), len(moving))
            limits = _limits(spec, moving)
            velocities = _velocities(spec, moving)
            _check_carry(spec, moving, limits)
            if spec.gripper is not None:
                gap = finger_gap(loaded, spec)
                if spec.gripper.opening > gap + OPENING_TOLERANCE:
                    raise StalmError(
                        f"gripper.opening: {spec.gripper.opening} m is wider than the fingers "
                        f"open (their collision geometry is {gap:.4f} m apart)"
                    )
            digest = content_hash(urdf, collision_files(loaded))
    except StalmError as error:
        raise StalmError(f"{source}: {error}") from None
    return Robot(spec, source, urdf, digest, chain, limits, velocities)


def tool_offset_matrix(spec: RobotSpec) -> np.ndarray:
    """The grasp frame in the tool link's frame (4x4)."""
    roll, pitch, yaw = spec.tool_offset.rpy
    quat = p.getQuaternionFromEuler((roll, pitch, yaw))
    matrix = np.eye(4)
    matrix[:3, :3] = matrix_from_quat(quat)
    matrix[:3, 3] = spec.tool_offset.xyz
    return matrix
