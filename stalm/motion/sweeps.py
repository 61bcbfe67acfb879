"""Motions planned without movable objects, and what their swept volume touches.

Occlusion predicates (paper §3.2) plan a motion ignoring movables, then test the swept volume
against each movable object and closed door. A :class:`SweptMotion` keeps the dense motion so
that when one object moves, only that object needs testing again (Appendix A's "cache all the
collisions and reuse them"). Collision with one obstacle does not depend on the others, so a
motion's hit set is exactly the union of per-obstacle tests.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from stalm.motion.base_motion import SE2, BasePath, densify
from stalm.motion.colliders import Collider
from stalm.world.state import Grasp, ObjectPose

Conf = tuple[float, ...]


@dataclass(frozen=True)
class ArmSegment:
    """Arm configurations at one standing pose, carrying ``held`` (or nothing), during which
    ``ignore`` (the object being grasped or released) is not an obstacle."""

    base: SE2
    confs: tuple[Conf, ...]
    held: Grasp | None = None
    ignore: str | None = None


@dataclass(frozen=True)
class BaseSegment:
    """The base driving a path with the arm folded and the hand empty."""

    waypoints: tuple[SE2, ...]


@dataclass(frozen=True)
class ObjectAt:
    """An object standing at a pose (a placement): overlaps count as occlusions."""

    obj: str
    pose: ObjectPose


Segment = ArmSegment | BaseSegment | ObjectAt


Fan = tuple[tuple[float, float, float, float], ...]
"""Arm reach lines (mount x, y, hand x, y) along a motion, seen from above."""

ARM_BULGE = 0.35
"""How far (m) any arm link strays, seen from above, from the line between the arm's mount and
its hand (the elbow bulges sideways), with a margin."""


@dataclass(frozen=True)
class SweptMotion:
    """A motion and the names of the movable objects and doors its swept volume touches.

    ``fan`` records where the arm reached at every configuration of its arm segments, so
    :meth:`near` and :func:`sweep_near` can tell cheaply what an object at a new pose could
    touch.
    """

    segments: tuple[Segment, ...]
    hits: frozenset[str]
    fan: Fan = ()
    held_reach: float = 0.0

    def near(self, x: float, y: float, radius: float) -> bool:
        """Could this motion touch an object of ``radius`` standing at (x, y)? Conservative."""
        margin = radius + self.held_reach
        for segment in self.segments:
            if isinstance(segment, BaseSegment):
                reach = BASE_FOOTPRINT + margin
                points = [(w[0], w[1]) for w in segment.waypoints]
            elif isinstance(segment, ObjectAt):
                reach = 0.5 + margin
                points = [(segment.pose.x, segment.pose.y)]
            else:
                continue
            if any(math.hypot(px - x, py - y) < reach for px, py in points):
                return True
        reach = ARM_BULGE + margin
        return any(_point_segment_distance(x, y, line) < reach for line in self.fan)


BASE_FOOTPRINT = 0.75
"""Radius (m) around the base centre that the robot with its folded arm occupies."""


def _point_segment_distance(x: float, y: float, line: tuple[float, float, float, float]) -> float:
    ax, ay, bx, by = line
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0.0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy) / length2))
    return math.hypot(x - (ax + t * dx), y - (ay + t * dy))


def base_segment(path: BasePath, resolution: float) -> BaseSegment:
    return BaseSegment(tuple(densify(path, resolution)))


def sweep(
    collider: Collider, segments: Iterable[Segment], stop_at: frozenset[int] = frozenset()
) -> tuple[frozenset[int], Fan]:
    """Every body touched anywhere along ``segments`` (besides the robot and what it holds),
    and the arm's reach lines, as ``collider`` finds them (both engines give the same bodies).
    Once a body of ``stop_at`` is touched the sweep ends there (its caller refuses the
    motion whatever else it touches).

    The caller sets the world (which objects stand where); this moves only the robot, the
    object it holds and, for an :class:`ObjectAt`, that object.
    """
    sim = collider.sim
    hits: set[int] = set()
    fan: list[tuple[float, float, float, float]] = []
    robot = (sim.bodies.base, sim.bodies.arm)
    for segment in segments:
        if isinstance(segment, ObjectAt):
            sim.attach(None)
            sim.place_object(segment.obj, segment.pose)
            hits |= sim.contacts_of([sim.bodies.objects[segment.obj]], robot)
        elif isinstance(segment, ArmSegment):
            sim.attach(segment.held)
            ignore = {sim.bodies.objects[segment.ignore]} if segment.ignore is not None else set()
            sim.set_base_only(segment.base)
            # the base stands still while the arm moves: what it touches is tested once
            base, moving = sim.robot_bodies()[0], sim.robot_bodies()[1:]
            hits |= sim.contacts_of([base], ignore | set(moving))
            touched, reach = collider.arm_touches(
                segment.base, segment.confs, moving, ignore, stop_at
            )
            hits |= touched
            fan.extend(reach)
            if hits & stop_at:
                break
        else:
            sim.attach(None)
            hits |= collider.route_touches(segment.waypoints, set())
    sim.attach(None)
    return frozenset(hits), tuple(fan)


def sweep_near(
    collider: Collider, motion: SweptMotion, body: int, x: float, y: float, radius: float
) -> bool:
    """Does ``motion`` touch ``body`` standing at (x, y)? Only the configurations whose reach
    passes within range of it are tested, against it alone, by ``collider`` (both engines
    give the same answer)."""
    sim = collider.sim
    margin = radius + motion.held_reach
    lines = iter(motion.fan)
    hit = False
    for segment in motion.segments:
        if isinstance(segment, ObjectAt):
            sim.attach(None)
            sim.place_object(segment.obj, segment.pose)
            hit = sim.touches([sim.bodies.objects[segment.obj]], body)
        elif isinstance(segment, ArmSegment):
            near = [
                conf
                for conf in segment.confs
                if _point_segment_distance(x, y, next(lines)) < ARM_BULGE + margin
            ]
            objects = sim.bodies.objects
            # the object being grasped or released, or carried, is not its own obstacle
            ignored = (segment.ignore is not None and objects[segment.ignore] == body) or (
                segment.held is not None and objects[segment.held.obj] == body
            )
            if near and not ignored:
                sim.attach(segment.held)
                hit = collider.arm_touches_body(segment.base, near, body)
        else:
            sim.attach(None)
            reach = BASE_FOOTPRINT + margin
            poses = [p for p in segment.waypoints if math.hypot(p[0] - x, p[1] - y) < reach]
            hit = collider.route_touches_body(poses, body)
        if hit:
            break
    sim.attach(None)
    return hit
