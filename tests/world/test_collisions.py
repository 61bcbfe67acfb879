"""Collision queries ask only about the queried bodies' pairs (``Sim.contacts_of``).

The collision masks change with every query's bodies, so these tests switch roles back and
forth and check that each query still sees exactly what touches its own bodies.
"""

from __future__ import annotations

import pybullet as p

from stalm.world.scene import Sim
from stalm.world.state import ObjectPose


def test_each_query_sees_what_touches_its_bodies_as_roles_switch(problems) -> None:
    problem = problems["P2"]
    with Sim(problem.spec) as sim:
        sim.set_state(problem.initial_state)
        first, second = problem.spec.objects[0].name, problem.spec.objects[1].name
        a, b = sim.bodies.objects[first], sim.bodies.objects[second]
        pose = problem.initial_state.pose(first)
        # the second object pushed into the first: each query about one of them sees the other
        sim.place_object(second, ObjectPose.make(pose.x + 0.01, pose.y, pose.z, pose.yaw))
        assert b in sim.contacts_of([a])
        assert a in sim.contacts_of([b])
        # the robot, far from both, touches neither, although they touch each other
        robot_hits = sim.robot_contacts()
        assert a not in robot_hits and b not in robot_hits
        # asked about together, they are not each other's hits
        assert not {a, b} & sim.contacts_of([a, b])
        # and once apart, the first query sees nothing of the second again
        sim.set_state(problem.initial_state)
        assert b not in sim.contacts_of([a])


def test_a_body_made_after_the_scene_can_be_queried(problems) -> None:
    problem = problems["P2"]
    with Sim(problem.spec) as sim:
        sim.set_state(problem.initial_state)
        sim.robot_contacts()  # the masks are set for the scene's bodies
        first = problem.spec.objects[0].name
        pose = problem.initial_state.pose(first)
        shape = p.createCollisionShape(
            p.GEOM_BOX, halfExtents=[0.05, 0.05, 0.05], physicsClientId=sim.client
        )
        centre = [pose.x, pose.y, pose.z]
        box = p.createMultiBody(1.0, shape, -1, centre, physicsClientId=sim.client)
        assert sim.bodies.objects[first] in sim.contacts_of([box])
