from __future__ import annotations

from pathlib import Path

import numpy as np

from stalm.domain.actions import Open, Pick
from stalm.viz.animate import plan_frames, save_gif


def two_p2_actions(domain):  # type: ignore[no-untyped-def]
    """P2's door opened and bottle1 picked: (drawn action, state after it) for each."""
    rng = np.random.default_rng(2)
    state = domain.problem.initial_state
    pairs = []
    for action in (Open("kitchen_door"), Pick("bottle1")):
        drawn, outcome = domain.sample_and_step(state, action, rng)
        assert drawn is not None and outcome.feasible
        pairs.append((drawn, outcome.state))
        state = outcome.state
    return pairs


def test_a_plan_animates_to_a_gif(domain_factory, tmp_path: Path) -> None:
    domain = domain_factory("P2")
    pairs = two_p2_actions(domain)
    frames = plan_frames(domain.sim, domain.problem.initial_state, pairs, size=48)
    # the start, base motion, arm motion and the door swinging for each action
    assert len(frames) > 10
    first, last = np.asarray(frames[0]), np.asarray(frames[-1])
    assert first.shape == (48, 96, 3) and not np.array_equal(first, last)
    path = save_gif(frames, tmp_path / "plan.gif")
    assert path.read_bytes()[:6] == b"GIF89a"
