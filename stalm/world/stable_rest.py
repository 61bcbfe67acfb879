"""Does an object rest where it stands, or only balance there?

:func:`~stalm.world.physics_check.unsettled_objects` settles a scene once from the poses a
file gives. An object balanced on a point or an edge passes that (nothing pushes it off its
balance in a symmetric start), yet topples in another scene once a rounding or a neighbour
tips it: a procedural toy of ``pybullet_data`` that stood still for 8 s alone fell over in a
generated scene within 1 s. :func:`why_it_does_not_rest` also starts the object tipped
:data:`TIP_DEG` toward each side; an object that rests comes back each time, one that
balances falls. It also settles longer (:data:`SETTLE_SECONDS`: some toys creep over for
seconds before they fall) and allows less (:data:`MOST_TILT_DEG`, :data:`MOST_MOVE_M`) than a
plan's check, so that what is kept rests with room to spare.
"""

from __future__ import annotations

import math

import pybullet as p

from stalm.world.physics_check import TIME_STEP, PhysicsWorld
from stalm.world.problem import Problem

TIP_DEG = 3.0
"""How far the object starts tipped toward each of four sides (degrees)."""
SETTLE_SECONDS = 4.0
"""How long each start is settled (s)."""
MOST_TILT_DEG = 2.0
"""The most an object may lean after settling, from any start (degrees)."""
MOST_MOVE_M = 0.005
"""The most its frame may move from where it stands (m)."""
TIPS = ((0.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))
"""The starts: upright, then tipped about the x axis both ways and the y axis both ways."""


def why_it_does_not_rest(problem: Problem, name: str) -> str | None:
    """Why object ``name`` of ``problem`` does not rest where the problem's initial state
    stands it (which start, how far it leaned or moved), or None when it rests from every
    start of :data:`TIPS`."""
    state = problem.initial_state
    pose = state.pose(name)
    hx, hy, _ = problem.spec.object(name).half_extents
    # tipped about its bottom centre, one edge would sink into the support: lifted clear
    lift = math.hypot(hx, hy) * math.sin(math.radians(TIP_DEG)) + 0.001
    world = PhysicsWorld(problem)
    try:
        for ax, ay in TIPS:
            world.show(None, state)
            if ax or ay:
                tip = math.radians(TIP_DEG)
                tipped = p.getQuaternionFromEuler([ax * tip, ay * tip, pose.yaw])
                world.put(name, (pose.x, pose.y, pose.z + lift), tipped)
            world.settle(round(SETTLE_SECONDS / TIME_STEP))
            drift = world.drift(name, pose)
            if drift.tilt_deg > MOST_TILT_DEG or drift.displacement_m > MOST_MOVE_M:
                start = "upright" if not (ax or ay) else f"tipped {TIP_DEG:g} deg"
                return (
                    f"started {start}, it leaned {drift.tilt_deg:.1f} deg and moved "
                    f"{drift.displacement_m * 1000:.1f} mm in {SETTLE_SECONDS:g} s"
                )
        return None
    finally:
        world.close()
