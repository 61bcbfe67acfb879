"""Building one problem's bodies in a PyBullet client: floor, walls, regions, doors, objects and
the robot (base cylinder and the arm its robot file names, the Panda by default).

Kept apart from :mod:`stalm.world.scene`, whose :class:`~stalm.world.scene.Sim` sets and
queries the world, because building runs once per simulator and is all shapes and colours,
while setting and querying run millions of times per trial. The bodies are created in a fixed
order (floor, walls, regions, doors, objects, base, arm), so a body's id is the same in every
simulator of one problem.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import pybullet as p
import pybullet_data

from stalm.geometry.transforms import Pose3, yaw_quat
from stalm.world.mesh_pieces import object_pieces
from stalm.world.object_spec import GRILL_HANDLE_HALF_HEIGHT, GRILL_HANDLE_REACH, ObjectSpec
from stalm.world.robot_description import Robot
from stalm.world.spec import DoorSpec, ProblemSpec, RegionSpec


@dataclass(frozen=True)
class ArmJoints:
    """Where a loaded arm's parts are in its PyBullet body: the joints a configuration
    lists, the finger joints with the positions they are held open at, the link a grasp is
    expressed in, and the grasp frame's offset from that link (None: the link itself, as the
    Panda's ``panda_grasptarget``)."""

    arm: tuple[int, ...]
    fingers: tuple[tuple[int, float], ...]
    grasp_link: int
    tool_offset: Pose3 | None
    finger_links: tuple[int, ...] = ()
    """The two links whose gap is the gripper's opening (none without a gripper)."""

    def grasp_pose(self, client: int, body: int) -> Pose3:
        """The grasp frame's world pose in ``body`` (the arm) as it stands now."""
        state = p.getLinkState(
            body, self.grasp_link, computeForwardKinematics=True, physicsClientId=client
        )
        pos, orn = state[4], state[5]
        if self.tool_offset is not None:
            pos, orn = p.multiplyTransforms(pos, orn, *self.tool_offset, physicsClientId=client)
        return (pos[0], pos[1], pos[2]), (orn[0], orn[1], orn[2], orn[3])

    @classmethod
    def of(cls, client: int, body: int, robot: Robot) -> ArmJoints:
        infos = [
            p.getJointInfo(body, j, physicsClientId=client)
            for j in range(p.getNumJoints(body, physicsClientId=client))
        ]
        names = {info[1].decode(): j for j, info in enumerate(infos)}
        links = {info[12].decode(): j for j, info in enumerate(infos)}
        gripper = robot.spec.gripper
        fingers = (
            ()
            if gripper is None
            else tuple((names[name], value) for name, value in gripper.finger_joints.items())
        )
        offset = robot.spec.tool_offset
        tool = None
        if any(offset.xyz) or any(offset.rpy):
            tool = (offset.xyz, tuple(p.getQuaternionFromEuler(offset.rpy)))
        return cls(
            tuple(joint.index for joint in robot.arm_joints),
            fingers,
            robot.chain[-1].index,
            tool,
            () if gripper is None else tuple(links[name] for name in gripper.finger_links),
        )


class SceneAbandoned(Exception):
    """Building a scene was given up because its ``stop`` said so (a trial's deadline passed
    while a scene of thousands of objects was loading)."""


@dataclass
class Bodies:
    """PyBullet body ids by name and by role."""

    walls: dict[str, int] = field(default_factory=dict)
    regions: dict[str, int] = field(default_factory=dict)
    doors: dict[str, int] = field(default_factory=dict)
    objects: dict[str, int] = field(default_factory=dict)
    base: int = -1
    arm: int = -1
    floor: int = -1
    joints: ArmJoints = ArmJoints((), (), -1, None)

    def name_of(self, body: int) -> str:
        for group in (self.walls, self.regions, self.doors, self.objects):
            for name, bid in group.items():
                if bid == body:
                    return name
        if body in (self.base, self.arm):
            return "robot"
        return f"body{body}"


def build_bodies(
    client: int, problem: ProblemSpec, robot: Robot, stop: Callable[[], bool] | None = None
) -> Bodies:
    """Create every body of ``problem`` in ``client``, in a fixed order (the ids follow it).

    ``stop`` is asked before each object: once it says so, :exc:`SceneAbandoned` is raised
    (on a scene of thousands of objects, building alone can outlast a trial's budget)."""
    c = client
    bodies = Bodies()
    p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
    (x0, y0), (x1, y1) = problem.floor
    floor_visual = p.createVisualShape(
        p.GEOM_BOX,
        halfExtents=[(x1 - x0) / 2, (y1 - y0) / 2, 0.005],
        rgbaColor=[0.86, 0.84, 0.80, 1],
        physicsClientId=c,
    )
    bodies.floor = p.createMultiBody(
        0, -1, floor_visual, [(x0 + x1) / 2, (y0 + y1) / 2, -0.005], physicsClientId=c
    )
    for wall in problem.walls:
        bodies.walls[wall.name] = _box(
            c, [s / 2 for s in wall.size], wall.center, wall.yaw, wall.color
        )
    for region in problem.regions:
        bodies.regions[region.name] = _region_body(c, region)
    for door in problem.doors:
        bodies.doors[door.name] = _door_body(c, door)
    for obj in problem.objects:
        if stop is not None and stop():
            raise SceneAbandoned(f"gave up building the scene at object {len(bodies.objects)}")
        bodies.objects[obj.name] = _object_body(c, obj)
    _build_robot(c, bodies, robot)
    return bodies


def _box(
    client: int,
    half: Sequence[float],
    center: Sequence[float],
    yaw: float,
    color: Sequence[float],
    mass: float = 0.0,
) -> int:
    c = client
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(half), physicsClientId=c)
    vis = p.createVisualShape(
        p.GEOM_BOX, halfExtents=list(half), rgbaColor=list(color), physicsClientId=c
    )
    return int(p.createMultiBody(mass, col, vis, list(center), yaw_quat(yaw), physicsClientId=c))


def _region_body(client: int, region: RegionSpec) -> int:
    thickness = region.thickness if region.thickness is not None else region.top
    half = (region.size[0] / 2, region.size[1] / 2, thickness / 2)
    center = (region.center[0], region.center[1], region.top - thickness / 2)
    return _box(client, half, center, region.yaw, region.color)


def _door_body(client: int, door: DoorSpec) -> int:
    """Door frame origin at the hinge on the floor; the panel extends along its +x."""
    c = client
    panel_half = [door.width / 2, door.thickness / 2, door.height / 2]
    panel_pos = [door.width / 2, 0.0, door.height / 2]
    handle_half = [0.02, door.thickness / 2 + 0.05, 0.06]
    handle_pos = [door.handle_distance, 0.0, door.handle_height]
    col = p.createCollisionShapeArray(
        [p.GEOM_BOX, p.GEOM_BOX],
        halfExtents=[panel_half, handle_half],
        collisionFramePositions=[panel_pos, handle_pos],
        physicsClientId=c,
    )
    vis = p.createVisualShapeArray(
        [p.GEOM_BOX, p.GEOM_BOX],
        halfExtents=[panel_half, handle_half],
        visualFramePositions=[panel_pos, handle_pos],
        rgbaColors=[list(door.color), [0.85, 0.75, 0.2, 1.0]],
        physicsClientId=c,
    )
    # mass > 0 although physics never runs: Bullet refreshes the broadphase bounds only of
    # non-static bodies, so a static door moved by a reset would keep stale bounds
    return int(
        p.createMultiBody(
            1.0,
            col,
            vis,
            [door.hinge[0], door.hinge[1], 0.0],
            yaw_quat(door.closed_yaw),
            physicsClientId=c,
        )
    )


def _object_body(client: int, obj: ObjectSpec) -> int:
    """Object frame origin at the centre of its bottom face, so z is the support height."""
    col, vis = object_shapes(client, obj)
    return int(p.createMultiBody(0.1, col, vis, [0, 0, -10.0], physicsClientId=client))


def object_shapes(client: int, obj: ObjectSpec) -> tuple[int, int]:
    """The collision and visual shapes of ``obj`` in ``client``, placed in the object's frame
    (origin at the centre of its bottom face): the planner's scene and the physics check of
    a plan build every object from these same shapes."""
    c = client
    color = list(obj.color)
    if obj.shape == "grill":
        assert obj.size is not None
        sx, sy, sz = obj.size
        body_half = [sx / 2, sy / 2, sz / 2]
        handle_half = [GRILL_HANDLE_HALF_HEIGHT, GRILL_HANDLE_REACH / 2, GRILL_HANDLE_HALF_HEIGHT]
        handle_z = obj.handle_z
        offsets = [
            [0.0, 0.0, sz / 2],
            [0.0, sy / 2 + GRILL_HANDLE_REACH / 2, handle_z],
            [0.0, -(sy / 2 + GRILL_HANDLE_REACH / 2), handle_z],
        ]
        halves = [body_half, handle_half, handle_half]
        col = p.createCollisionShapeArray(
            [p.GEOM_BOX] * 3,
            halfExtents=halves,
            collisionFramePositions=offsets,
            physicsClientId=c,
        )
        vis = p.createVisualShapeArray(
            [p.GEOM_BOX] * 3,
            halfExtents=halves,
            visualFramePositions=offsets,
            rgbaColors=[color, [0.15, 0.15, 0.15, 1], [0.15, 0.15, 0.15, 1]],
            physicsClientId=c,
        )
    elif obj.shape == "box":
        half = list(obj.half_extents)
        centre = [0.0, 0.0, half[2]]
        col = p.createCollisionShape(
            p.GEOM_BOX, halfExtents=half, collisionFramePosition=centre, physicsClientId=c
        )
        vis = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=half,
            rgbaColor=color,
            visualFramePosition=centre,
            physicsClientId=c,
        )
    elif obj.shape == "mesh":
        col, vis = _mesh_shapes(client, obj)
    else:
        assert obj.radius is not None and obj.height is not None
        col = p.createCollisionShape(
            p.GEOM_CYLINDER,
            radius=obj.radius,
            height=obj.height,
            collisionFramePosition=[0, 0, obj.height / 2],
            physicsClientId=c,
        )
        vis = p.createVisualShape(
            p.GEOM_CYLINDER,
            radius=obj.radius,
            length=obj.height,
            rgbaColor=color,
            visualFramePosition=[0, 0, obj.height / 2],
            physicsClientId=c,
        )
    return int(col), int(vis)


def _mesh_shapes(client: int, obj: ObjectSpec) -> tuple[int, int]:
    """A mesh object collides as its convex pieces (a compound of their hulls) and looks like
    its own OBJ, both scaled and moved into the object's frame."""
    outline, pieces = obj.outline, object_pieces(obj)
    scale = [outline.scale] * 3
    col = p.createCollisionShape(
        p.GEOM_MESH,
        fileName=str(pieces.collision_file),
        meshScale=scale,
        collisionFramePosition=list(pieces.frame_position),
        physicsClientId=client,
    )
    vis = p.createVisualShape(
        p.GEOM_MESH,
        fileName=str(outline.path),
        meshScale=scale,
        rgbaColor=list(obj.color),
        visualFramePosition=list(pieces.frame_position),
        physicsClientId=client,
    )
    return int(col), int(vis)


def _build_robot(client: int, bodies: Bodies, robot: Robot) -> None:
    c = client
    mount = robot.platform
    col = p.createCollisionShape(
        p.GEOM_CYLINDER,
        radius=mount.base_radius,
        height=mount.base_height,
        collisionFramePosition=[0, 0, mount.base_height / 2],
        physicsClientId=c,
    )
    vis = p.createVisualShapeArray(
        [p.GEOM_CYLINDER, p.GEOM_BOX],
        radii=[mount.base_radius, 0.0],
        lengths=[mount.base_height, 0.0],
        halfExtents=[[0, 0, 0], [0.06, 0.06, 0.5]],
        visualFramePositions=[
            [0, 0, mount.base_height / 2],
            [mount.arm_mount_forward, 0, 0.5],
        ],
        rgbaColors=[[0.25, 0.25, 0.3, 1], [0.5, 0.5, 0.55, 1]],
        physicsClientId=c,
    )
    bodies.base = int(p.createMultiBody(5.0, col, vis, [0, 0, 0], physicsClientId=c))
    bodies.arm = int(
        p.loadURDF(str(robot.urdf_path), [0, 0, 1], useFixedBase=True, physicsClientId=c)
    )
    bodies.joints = ArmJoints.of(c, bodies.arm, robot)
    for link in range(-1, p.getNumJoints(bodies.arm, physicsClientId=c)):
        p.setCollisionFilterPair(bodies.arm, bodies.base, link, -1, 0, physicsClientId=c)
    for joint, value in bodies.joints.fingers:
        p.resetJointState(bodies.arm, joint, value, physicsClientId=c)
