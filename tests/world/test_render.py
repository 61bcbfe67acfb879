from __future__ import annotations

import numpy as np

from stalm.viz.render import render_state
from stalm.world.problem import Problem
from stalm.world.scene import Sim


def test_every_problem_renders_a_nonblank_picture(problems: dict[str, Problem]) -> None:
    for problem in problems.values():
        with Sim(problem.spec) as sim:
            image = render_state(sim, problem.initial_state, size=96)
        pixels = np.asarray(image)
        assert image.size == (192, 96)
        assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 10, problem.name
