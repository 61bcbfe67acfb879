"""Shared fixtures: problems, one simulator-backed domain per problem, a private cache dir."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from stalm.domain.mdp import Domain
from stalm.world.problem import Problem, load_problem

PROBLEM_NAMES = ("P1", "P2", "P3", "P4", "P5", "P6")


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """Roadmaps and replies are cached under a per-session directory, never the user's."""
    path = tmp_path_factory.mktemp("stalm-cache")
    old = os.environ.get("STALM_CACHE_DIR")
    os.environ["STALM_CACHE_DIR"] = str(path)
    yield path
    if old is None:
        os.environ.pop("STALM_CACHE_DIR", None)
    else:
        os.environ["STALM_CACHE_DIR"] = old


@pytest.fixture(scope="session")
def problems() -> dict[str, Problem]:
    return {name: load_problem(name) for name in PROBLEM_NAMES}


@pytest.fixture(scope="session")
def domain_factory(problems: dict[str, Problem]) -> Iterator[object]:
    """Domains are built once per problem per session (each owns a PyBullet client)."""
    made: dict[str, Domain] = {}

    def get(name: str) -> Domain:
        if name not in made:
            made[name] = Domain.create(problems[name])
        return made[name]

    yield get
    for domain in made.values():
        domain.close()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)


@pytest.fixture(scope="session")
def initial_literals(domain_factory) -> Iterator[object]:
    """Predicates of each problem's initial state, computed once per session."""
    from stalm.predicates.engine import PredicateEngine

    computed: dict[str, frozenset[object]] = {}

    def get(name: str) -> frozenset[object]:
        if name not in computed:
            domain = domain_factory(name)
            engine = PredicateEngine(domain.problem, domain.sim, domain.base_planner)
            computed[name] = engine.compute(domain.problem.initial_state).literals
        return computed[name]

    yield get
