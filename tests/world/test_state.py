from __future__ import annotations

import numpy as np

from stalm.domain.actions import Open, Pick
from stalm.world.problem import Problem
from stalm.world.scene import Sim
from stalm.world.state import ObjectPose, State


def test_state_round_trips_through_the_simulator(problems: dict[str, Problem]) -> None:
    for problem in problems.values():
        with Sim(problem.spec) as sim:
            state = problem.initial_state
            sim.set_state(state)
            assert sim.read_state() == state


def test_state_with_a_held_object_and_open_door_round_trips(
    domain_factory, rng: np.random.Generator
) -> None:
    domain = domain_factory("P2")
    state = domain.problem.initial_state
    opened = domain.sample_and_step(state, Open("kitchen_door"), rng)[1].state
    _action, outcome = domain.sample_and_step(opened, Pick("bottle2"), rng)
    assert outcome.feasible, outcome.failure
    holding = outcome.state
    assert holding.held is not None and holding.is_open("kitchen_door")
    domain.sim.set_state(holding)
    assert domain.sim.read_state() == holding
    assert hash(domain.sim.read_state()) == hash(holding)
    assert State.from_json(holding.to_json()) == holding


def test_states_are_canonical_and_hashable() -> None:
    a = ObjectPose.make(1.0000000001, 2.0, 3.0, np.pi)
    b = ObjectPose.make(1.0, 2.0, 3.0, -np.pi + 1e-9)
    assert a == b and hash(a) == hash(b)
