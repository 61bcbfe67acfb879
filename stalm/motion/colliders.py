"""What a robot motion touches: the PyBullet reference and the batched engine, one interface.

Three questions are asked of motions planned by the operators, the predicates and the
streams: every body a motion touches anywhere (occlusion predicates sweep whole motions), the
bodies touched at the first configuration that touches any (a sampler's feasibility check, a
base path's first blocked edge), and whether a motion touches one given body (the cached
predicates' re-sweep after a PLACE). :class:`PyBulletCollider` answers them configuration by
configuration with PyBullet's contact queries (the reference). :class:`BatchCollider` asks the
compiled candidate test of :mod:`stalm.motion.collision_kernels` about all configurations of a
motion at once and confirms each candidate with the same PyBullet query the reference makes;
since the candidate test never misses a contact (it is conservative), both give the same
bodies, and the batched engine pays PyBullet only for the few configurations near something.

Contact means what it means everywhere in stalm: penetration deeper than
:data:`~stalm.world.scene.PENETRATION_TOLERANCE` (``Sim.contacts_of``, ``Sim.touches``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Literal, Protocol

import numpy as np

from stalm.motion.arm_model import arm_of
from stalm.motion.collision_kernels import candidate_steps
from stalm.motion.scene_primitives import ScenePrimitives
from stalm.world.scene import Sim

Engine = Literal["batched", "pybullet"]
ENGINES: tuple[str, ...] = ("batched", "pybullet")
Conf = tuple[float, ...]
SE2 = tuple[float, float, float]
Reach = tuple[float, float, float, float]
"""A reach line seen from above: the arm's mount (x, y) and the grasp point (x, y)."""


def reach_line(sim: Sim, stand: SE2, conf: Conf) -> Reach:
    """The reach line of ``conf`` (lift, joints) at ``stand``, by forward kinematics."""
    arm = arm_of(sim)
    mount = sim.arm_mount(stand, conf[0])
    hand = arm.frames(arm.base_frame(mount), np.asarray(conf[1:]))[arm.grasp_frame]
    return (mount.x, mount.y, float(hand[0, 3]), float(hand[1, 3]))


class Collider(Protocol):
    """The collision questions motions ask (see the module docstring)."""

    sim: Sim

    def arm_touches(
        self,
        stand: SE2,
        confs: Sequence[Conf],
        moving: Sequence[int],
        ignore: set[int],
        stop_at: frozenset[int] = frozenset(),
    ) -> tuple[set[int], list[Reach]]:
        """Every body the arm (with what it holds) touches along ``confs`` at ``stand``, and
        the reach line (mount x, y, grasp point x, y) of each configuration. Once a body of
        ``stop_at`` is touched the rest is not looked at (a motion through the static scene
        is refused whatever else it touches)."""

    def arm_first_touch(self, stand: SE2, confs: Sequence[Conf], ignore: set[int]) -> set[int]:
        """The bodies touched at the first configuration that touches any (empty: none)."""

    def route_first_touch(self, waypoints: Sequence[SE2], ignore: set[int]) -> tuple[int, set[int]]:
        """The index of the first base pose at which the robot touches something, and what
        it touches there (-1 and nothing if none)."""

    def route_touches(self, waypoints: Sequence[SE2], ignore: set[int]) -> set[int]:
        """Every body the robot touches at any of the base poses ``waypoints`` (the arm and
        what it holds as the simulator has them)."""

    def arm_touches_body(self, stand: SE2, confs: Sequence[Conf], body: int) -> bool:
        """Does the robot (base, arm, what it holds) touch ``body`` at any of ``confs`` at
        ``stand``? Asked again of a cached motion when ``body`` has moved."""

    def route_touches_body(self, waypoints: Sequence[SE2], body: int) -> bool:
        """Does the robot touch ``body`` at any of the base poses ``waypoints``?"""


class PyBulletCollider:
    """The reference: each configuration set in PyBullet and queried (``Sim.contacts_of``)."""

    def __init__(self, sim: Sim) -> None:
        self.sim = sim

    def arm_touches(
        self,
        stand: SE2,
        confs: Sequence[Conf],
        moving: Sequence[int],
        ignore: set[int],
        stop_at: frozenset[int] = frozenset(),
    ) -> tuple[set[int], list[Reach]]:
        sim = self.sim
        hits: set[int] = set()
        for conf in confs:
            sim.set_arm_at(sim.arm_mount(stand, conf[0]), conf[1:])
            hits |= sim.contacts_of(moving, ignore | {sim.bodies.base})
            if hits & stop_at:
                break
        return hits, [reach_line(sim, stand, conf) for conf in confs]

    def arm_first_touch(self, stand: SE2, confs: Sequence[Conf], ignore: set[int]) -> set[int]:
        for conf in confs:
            self.sim.set_arm(stand, conf[0], conf[1:])
            hits = self.sim.robot_contacts(ignore)
            if hits:
                return hits
        return set()

    def route_first_touch(self, waypoints: Sequence[SE2], ignore: set[int]) -> tuple[int, set[int]]:
        for index, pose in enumerate(waypoints):
            self.sim.set_base_only(pose)
            hits = self.sim.robot_contacts(ignore)
            if hits:
                return index, hits
        return -1, set()

    def route_touches(self, waypoints: Sequence[SE2], ignore: set[int]) -> set[int]:
        hits: set[int] = set()
        for pose in waypoints:
            self.sim.set_base_only(pose)
            hits |= self.sim.robot_contacts(ignore)
        return hits

    def arm_touches_body(self, stand: SE2, confs: Sequence[Conf], body: int) -> bool:
        sim = self.sim
        for conf in confs:
            sim.set_arm(stand, conf[0], conf[1:])
            if sim.touches(sim.robot_bodies(), body):
                return True
        return False

    def route_touches_body(self, waypoints: Sequence[SE2], body: int) -> bool:
        sim = self.sim
        for pose in waypoints:
            sim.set_base_only(pose)
            if sim.touches(sim.robot_bodies(), body):
                return True
        return False


class BatchCollider:
    """The batched engine: candidates from the compiled test, confirmed by PyBullet."""

    def __init__(self, sim: Sim) -> None:
        self.sim = sim
        self._scene = ScenePrimitives(sim)
        self._columns = self._scene.columns
        self._column_of = self._scene.column_of
        self._arm = arm_of(sim)
        self._conf_length = 1 + self._arm.dof

    def _candidates(
        self,
        stands: np.ndarray,
        confs: np.ndarray,
        ignore: Iterable[int],
        with_base: bool,
        only: int | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        boxes, cylinders = self._scene.world(ignore, only)
        links, centres, radii, groups, held_boxes, held_box_group = self._scene.with_held()
        frames, reach = self._arm.step_frames(stands, confs)
        flags = candidate_steps(
            stands,
            frames,
            self._arm.grasp_frame,
            links,
            centres,
            radii,
            groups,
            len(self._scene.groups),
            held_boxes,
            held_box_group,
            self._scene.base_box if with_base else np.zeros((0, 16)),
            boxes,
            cylinders,
            len(self._columns),
        )
        return flags, reach

    def _confirm(
        self,
        flags: np.ndarray,
        set_step: Callable[[int], None],
        moving: Callable[[], Sequence[int]],
        first: bool,
        stop_at: frozenset[int] = frozenset(),
    ) -> tuple[int, set[int]]:
        """PyBullet's answer for the flagged (step, body) pairs: with ``first``, the first
        step where any is confirmed and all its confirmed bodies; else every body confirmed at
        some step (step index -1), stopping once one of ``stop_at`` is."""
        hits: set[int] = set()
        open_columns = np.asarray(flags.any(axis=0))
        steps, columns = np.nonzero(flags)
        start = 0
        while start < len(steps):
            step = steps[start]
            end = start
            while end < len(steps) and steps[end] == step:
                end += 1
            pending = [int(c) for c in columns[start:end] if open_columns[c]]
            start = end
            if not pending:
                continue
            set_step(int(step))
            bodies = moving()
            found = {
                self._columns[c] for c in pending if self.sim.touches(bodies, self._columns[c])
            }
            if first and found:
                return int(step), found
            for body in found:
                open_columns[self._column_of[body]] = False
            hits |= found
            if hits & stop_at:
                break
        return -1, hits

    # ------------------------------------------------------------------ the questions
    def arm_touches(
        self,
        stand: SE2,
        confs: Sequence[Conf],
        moving: Sequence[int],
        ignore: set[int],
        stop_at: frozenset[int] = frozenset(),
    ) -> tuple[set[int], list[Reach]]:
        sim = self.sim
        array = np.asarray(confs, dtype=float).reshape(-1, self._conf_length)
        stands = np.tile(np.asarray(stand, dtype=float), (len(array), 1))
        flags, reach = self._candidates(stands, array, ignore | {sim.bodies.base}, False)

        def set_step(step: int) -> None:
            conf = confs[step]
            sim.set_arm_at(sim.arm_mount(stand, conf[0]), conf[1:])

        _, hits = self._confirm(flags, set_step, lambda: moving, first=False, stop_at=stop_at)
        return hits, [(a, b, c, d) for a, b, c, d in reach.tolist()]

    def arm_first_touch(self, stand: SE2, confs: Sequence[Conf], ignore: set[int]) -> set[int]:
        sim = self.sim
        if not confs:
            return set()
        array = np.asarray(confs, dtype=float).reshape(-1, self._conf_length)
        stands = np.tile(np.asarray(stand, dtype=float), (len(array), 1))
        flags, _ = self._candidates(stands, array, ignore | {sim.bodies.base}, False)
        arm = sim.robot_bodies()[1:]
        sim.set_base_only(stand)
        base_hits = sim.contacts_of([sim.bodies.base], ignore | set(arm))
        if base_hits:  # the reference stops at the first configuration: the base touches there
            flags[1:] = False

        def set_step(step: int) -> None:
            sim.set_arm(stand, confs[step][0], confs[step][1:])

        _, hits = self._confirm(flags, set_step, sim.robot_bodies, first=True)
        return (hits - {sim.bodies.base}) | base_hits

    def _route_flags(
        self, waypoints: Sequence[SE2], ignore: set[int], only: int | None = None
    ) -> np.ndarray:
        conf = np.array([self.sim.arm_conf()] * len(waypoints), dtype=float)
        stands = np.asarray(waypoints, dtype=float).reshape(-1, 3)
        flags, _ = self._candidates(stands, conf, ignore, True, only)
        return flags

    def route_first_touch(self, waypoints: Sequence[SE2], ignore: set[int]) -> tuple[int, set[int]]:
        if not waypoints:
            return -1, set()
        flags = self._route_flags(waypoints, ignore)
        return self._confirm(
            flags, lambda k: self.sim.set_base_only(waypoints[k]), self.sim.robot_bodies, first=True
        )

    def route_touches(self, waypoints: Sequence[SE2], ignore: set[int]) -> set[int]:
        if not waypoints:
            return set()
        flags = self._route_flags(waypoints, ignore)
        _, hits = self._confirm(
            flags,
            lambda k: self.sim.set_base_only(waypoints[k]),
            self.sim.robot_bodies,
            first=False,
        )
        return hits

    def arm_touches_body(self, stand: SE2, confs: Sequence[Conf], body: int) -> bool:
        sim = self.sim
        if not confs:
            return False
        sim.set_base_only(stand)  # the base stands still at every configuration
        if sim.touches([sim.bodies.base], body):
            return True
        array = np.asarray(confs, dtype=float).reshape(-1, self._conf_length)
        stands = np.tile(np.asarray(stand, dtype=float), (len(array), 1))
        flags, _ = self._candidates(stands, array, (), False, only=body)

        def set_step(step: int) -> None:
            sim.set_arm(stand, confs[step][0], confs[step][1:])

        step, _ = self._confirm(flags, set_step, sim.robot_bodies, first=True)
        return step >= 0

    def route_touches_body(self, waypoints: Sequence[SE2], body: int) -> bool:
        if not waypoints:
            return False
        flags = self._route_flags(waypoints, set(), only=body)
        step, _ = self._confirm(
            flags, lambda k: self.sim.set_base_only(waypoints[k]), self.sim.robot_bodies, first=True
        )
        return step >= 0


def make_collider(sim: Sim, engine: str) -> Collider:
    """The collider ``engine`` names ("batched" or "pybullet")."""
    if engine == "batched":
        return BatchCollider(sim)
    if engine == "pybullet":
        return PyBulletCollider(sim)
    raise ValueError(f"unknown collision engine {engine!r} (available: {', '.join(ENGINES)})")
