"""Shared fixtures: problems, one simulator-backed domain per problem, a private cache dir."""

from __future__ import annotations

import os
import pickle
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis.configuration import set_hypothesis_home_dir

from stalm.domain.mdp import Domain
from stalm.world.problem import Problem, load_problem

PROBLEM_NAMES = ("P1", "P2", "P3", "P4", "P5", "P6")
_HYPOTHESIS_HOME = pytest.StashKey[str]()


def pytest_configure(config: pytest.Config) -> None:
    """Hypothesis's folder (example database, caches; by default ./.hypothesis, which every
    pytest-xdist worker would write to) goes to a temporary folder of this process. It is set
    here because Hypothesis's plugin already writes to it while tests are collected."""
    folder = tempfile.mkdtemp(prefix="stalm-tests-hypothesis-")
    config.stash[_HYPOTHESIS_HOME] = folder
    set_hypothesis_home_dir(folder)


def pytest_unconfigure(config: pytest.Config) -> None:
    folder = config.stash.get(_HYPOTHESIS_HOME, None)
    if folder is not None:
        set_hypothesis_home_dir(None)
        shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """Roadmaps and replies are cached under a per-session directory, never the user's.

    Under pytest-xdist each worker is a session with its own base temporary directory, so
    workers share no cache files (a roadmap built by one is built again by the other).
    """
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


def _run_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder of this test run shared by its pytest-xdist workers (each worker's base
    temporary folder sits in the run's own one); the run's base folder without xdist."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@pytest.fixture(scope="session")
def initial_predicates(domain_factory, tmp_path_factory) -> Iterator[object]:
    """The predicate cache of each problem's initial state, computed once per test run.

    A full computation costs 5-15 s of CPU and a dozen tests need one, so they share it: the
    first worker to ask computes it (under a file lock) and leaves it, pickled, in the run's
    shared folder for the other workers. The cache is read only: ``PredicateEngine.update``
    returns a new cache and leaves its argument as it was.
    """
    from filelock import FileLock

    from stalm.predicates.engine import PredicateCache, PredicateEngine

    computed: dict[str, PredicateCache] = {}
    folder = _run_folder(tmp_path_factory)

    def compute(name: str) -> PredicateCache:
        domain = domain_factory(name)
        engine = PredicateEngine(domain.problem, domain.sim, domain.base_planner)
        return engine.compute(domain.problem.initial_state)

    def get(name: str) -> PredicateCache:
        if name not in computed:
            path = folder / f"initial-predicates-{name}.pickle"
            with FileLock(f"{path}.lock"):
                if path.exists():
                    computed[name] = pickle.loads(path.read_bytes())
                else:
                    computed[name] = compute(name)
                    path.write_bytes(pickle.dumps(computed[name]))
        return computed[name]

    yield get


@pytest.fixture(scope="session")
def initial_literals(initial_predicates) -> Iterator[object]:
    """Predicates of each problem's initial state, computed once per session."""

    def get(name: str) -> frozenset[object]:
        return initial_predicates(name).literals

    yield get
