"""The batched engine's scene rows are kept per body and made again only when the body moves:
after objects and a door move, and with different bodies ignored, the rows are what a fresh
scene makes (the cached rows are never marked in place)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from stalm.motion.scene_primitives import ScenePrimitives
from stalm.world.problem import load_problem
from stalm.world.scene import Sim

DATA = Path(__file__).parent / "data"


def test_the_rows_follow_every_move_and_every_ignore_as_a_fresh_scene_makes_them() -> None:
    problem = load_problem(DATA / "meshclutter20_seed5.yaml")  # meshes, boxes, a door
    with Sim(problem.spec) as sim:
        kept = ScenePrimitives(sim)
        objects = sim.bodies.objects
        meshes = [o.name for o in problem.spec.objects if o.shape == "mesh"]
        first = kept.world(ignore=[objects[meshes[0]]])
        again = kept.world(ignore=[])  # another ignore: the cached rows were not marked
        assert np.array_equal(again[0], ScenePrimitives(sim).world(ignore=[])[0])
        assert not np.array_equal(first[0][:, 15], again[0][:, 15])
        state = problem.initial_state
        pose = state.pose(meshes[1])
        moved = replace(pose, x=pose.x + 0.03, yaw=pose.yaw + 0.4)
        door = problem.spec.doors[0].name
        sim.set_state(state.with_changes(poses={meshes[1]: moved}, open_door=door))
        for ignore in ([], [objects[meshes[2]]]):
            rows, cylinders = kept.world(ignore=ignore)
            fresh_rows, fresh_cylinders = ScenePrimitives(sim).world(ignore=ignore)
            assert np.array_equal(rows, fresh_rows) and np.array_equal(cylinders, fresh_cylinders)
        assert not np.array_equal(kept.world(ignore=[])[0], again[0])  # they did move
        alone = objects[meshes[1]]
        only = kept.world(ignore=[], only=alone)[0]
        assert np.array_equal(only, ScenePrimitives(sim).world(ignore=[], only=alone)[0])
