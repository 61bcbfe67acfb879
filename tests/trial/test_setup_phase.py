"""A trial's set-up (the scene, the domain, the method's start) is inside its deadline and
has a phase of its own (issue 30, item 12).

On a scene of thousands of objects set-up alone can outlast a short budget; its seconds were
in ``total`` but in no phase, and the trial went on past its deadline. Here building P2's
scene is slowed until well past a tiny budget (so no wall-time bound is asserted, only that
the slow part's seconds are booked to ``setup``): the trial ends as 'timeout' without starting
the method, with the set-up phase recorded.
"""

from __future__ import annotations

import dataclasses
import time

import pytest

from stalm.planners.registry import build_planner
from stalm.trial import online
from stalm.world.scene import Sim
from tests.flat_settings import settings_of

BUDGET_S = 0.2
SLOW_S = 3 * BUDGET_S


@pytest.fixture
def slow_scene(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every scene takes at least SLOW_S to build."""
    build = Sim.__init__

    def slow_init(self: Sim, *args: object, **kwargs: object) -> None:
        time.sleep(SLOW_S)
        build(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Sim, "__init__", slow_init)


def test_a_set_up_that_outlasts_the_budget_ends_the_trial_as_a_timeout(
    problems, monkeypatch, slow_scene
) -> None:
    built = build_planner("uct", settings_of())
    assert isinstance(built, online.OnlinePlanner)
    started: list[object] = []

    def recorded_start(trial: online.Trial) -> online.Decider:
        started.append(trial)
        return built.start(trial)

    planner = dataclasses.replace(built, start=recorded_start)
    result = planner.solve(problems["P2"], seed=0, time_budget_s=BUDGET_S)
    assert result.termination == "timeout" and not result.success
    assert started == []  # the deadline had passed: the method never started
    assert result.plan == () and result.states == (problems["P2"].initial_state,)
    times = result.times
    assert times.setup >= SLOW_S  # the slow scene is booked to set-up
    assert times.setup <= times.total
    assert times.predicates == times.tree_search == times.execution == 0.0
    assert "setup" in result.to_json()["times"]


@pytest.mark.parametrize("planner", ["uct", "pddlstream-adaptive"])
def test_set_up_has_its_phase_in_every_trial(problems, slow_scene, planner: str) -> None:
    """Also the planner outside the online scaffold: its set-up seconds have their phase."""
    result = build_planner(planner, settings_of()).solve(
        problems["P2"], seed=0, time_budget_s=BUDGET_S
    )
    assert result.termination == "timeout"
    assert SLOW_S <= result.times.setup <= result.times.total


def test_the_deadline_stops_building_a_scene_between_two_objects(problems, monkeypatch) -> None:
    """P3's twelve objects, each slowed until the tiny budget has surely passed after the
    first: the scene is given up after it, the trial ends as 'timeout' with no counters."""
    from stalm.world import scene_build

    built: list[str] = []
    make = scene_build._object_body

    def slow_object(client: int, obj: object) -> int:
        built.append(obj.name)  # type: ignore[attr-defined]
        time.sleep(SLOW_S)
        return make(client, obj)  # type: ignore[arg-type]

    monkeypatch.setattr(scene_build, "_object_body", slow_object)
    p3 = problems["P3"]
    result = build_planner("uct", settings_of()).solve(p3, seed=0, time_budget_s=BUDGET_S)
    assert result.termination == "timeout" and not result.success
    assert len(built) == 1 < len(p3.spec.objects)  # the deadline passed during the first
    assert result.plan == () and result.states == (p3.initial_state,)
    assert SLOW_S <= result.times.setup <= result.times.total
    assert result.counters.collision_checks == 0
