"""P5's and P6's grill trap, as the paper built it (§4.4, Figure 6): the walled counter takes
the grill only at its open front, and a grill standing there leaves no room for anything else.

The walls are taller than the grill's handles and closer together than the handles' span, so
the grill cannot stand between them; in front of them its 0.54 m (handles included) leaves
under a can's width of the 0.6 m counter beside it and under a can's depth in front of it,
and the arm cannot reach over its 0.18 m body into the walled pocket behind it. Cans standing
in the pocket leave the front free for the grill.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.mdp import Domain
from stalm.domain.outcome import Infeasibility
from stalm.experiments.trap_check import check_record, trap_violations
from stalm.geometry.transforms import se2_to_world
from stalm.world.problem import Problem, load_problem
from stalm.world.relations import at_position
from stalm.world.spec import ProblemSpec
from stalm.world.state import ObjectPose, State
from tests.cli_runner import run_cli
from tests.domain.trap_sweep import Grid, sweep_can_placements

SEEDS = range(8)
TRAPS = {
    # problem: (walled counter, a can to place there, the goal's other objects)
    "P5": ("counter1", "sprite", ("coke", "sprite")),
    "P6": ("counter2", "coke", ("coke", "wine")),
}
POCKET = ((0.16, 0.09), (0.19, -0.1))
"""(u, v) in the walled pocket, at the back of the counter, for the other goal objects."""


def _opened(domain: Domain) -> State:
    rng = np.random.default_rng(0)
    for _ in range(10):
        _, outcome = domain.sample_and_step(domain.problem.initial_state, Open("kitchen_door"), rng)
        if outcome.feasible:
            return outcome.state
    raise AssertionError("the door did not open in 10 tries")


def _held(domain: Domain, state: State, obj: str) -> State:
    _, outcome = domain.sample_and_step(state, Pick(obj), np.random.default_rng(1))
    assert outcome.feasible, outcome.failure
    return outcome.state


def _with_poses(state: State, poses: dict[str, ObjectPose]) -> State:
    merged = dict(state.poses) | poses
    return State(
        tuple(sorted(merged.items())),
        state.open_doors,
        state.robot,
        state.held,
        state.held_yaw_offset,
    )


@pytest.mark.parametrize("name", sorted(TRAPS))
def test_the_grill_at_the_front_leaves_no_placement_on_its_counter(domain_factory, name) -> None:
    domain = domain_factory(name)
    counter, can, _ = TRAPS[name]
    state = _opened(domain)
    if name == "P5":  # the grill starts on counter2: put it on the walled counter first
        grill = _held(domain, state, "beef_grill")
        _, placed = domain.sample_and_step(
            grill, Place("beef_grill", "on", counter), np.random.default_rng(2)
        )
        assert placed.feasible, placed.failure
        state = placed.state
    pose = state.pose("beef_grill")
    region = domain.problem.spec.region(counter)
    assert at_position(domain.problem.spec, state, "beef_grill", "on", counter)
    assert abs(pose.x - region.center[0]) > 0.09, "only at the front, outside the walls"
    held = _held(domain, state, can)
    for seed in SEEDS:
        drawn = domain.samplers.place(held, Place(can, "on", counter), np.random.default_rng(seed))
        assert isinstance(drawn, Infeasibility), f"seed {seed}: {can} placed beside the grill"
        assert "beef_grill" in drawn.blockers


@pytest.mark.parametrize("name", sorted(TRAPS))
def test_with_the_others_in_the_walled_pocket_the_grill_goes_in_front(domain_factory, name) -> None:
    domain = domain_factory(name)
    counter, _, others = TRAPS[name]
    region = domain.problem.spec.region(counter)
    held = _held(domain, _opened(domain), "beef_grill")
    pocket = {}
    for obj, (u, v) in zip(others, POCKET, strict=True):
        x, y = se2_to_world((*region.center, region.yaw), u, v)
        pocket[obj] = ObjectPose.make(x, y, region.top, region.yaw)
    state = _with_poses(held, pocket)
    for seed in SEEDS:
        _, outcome = domain.sample_and_step(
            state, Place("beef_grill", "on", counter), np.random.default_rng(seed)
        )
        assert outcome.feasible, f"seed {seed}: {outcome.failure}"
        spec = domain.problem.spec
        assert all(at_position(spec, outcome.state, o, "on", counter) for o in others)


# ---------------------------------------------------------------- as every PLACE could draw


def _as_before_issue_41(problem: Problem) -> Problem:
    """The problem with the grill and walled counter it had before issue 41: an 0.18 m grill
    (handles at 3/4 of it) on a counter 0.6 m usable wide, where the arm reached over it."""
    data = problem.spec.model_dump(mode="json")
    counter = TRAPS[problem.name][0]
    for obj in data["objects"]:
        if obj["name"] == "beef_grill":
            obj["size"][2] = 0.18
            obj.pop("handle_height")
    for region in data["regions"]:
        if region["name"] == counter:
            region["usable"][1] = 0.6
    return Problem(ProblemSpec.model_validate(data), problem.source)


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["batched", "pybullet"])
@pytest.mark.parametrize("name", sorted(TRAPS))
def test_no_can_placement_anywhere_with_the_grill_anywhere_at_the_front(name, engine) -> None:
    counter, can, _ = TRAPS[name]
    result = sweep_can_placements(load_problem(name), counter, can, engine)
    assert result.grill_poses >= 3, "the grill has room at the front"
    assert result.checked_motions > 500, "placements behind the grill reach the motion check"
    assert result.feasible == ()


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(TRAPS))
def test_the_sweep_finds_the_arm_reaching_over_the_old_grill(name) -> None:
    counter, can, _ = TRAPS[name]
    old = _as_before_issue_41(load_problem(name))
    result = sweep_can_placements(old, counter, can, "batched", Grid(grill_u=2, grill_v=2))
    behind = [f for f in result.feasible if f.can[0] > f.grill[0] + 0.15]
    assert behind, "a can placed in the pocket behind the grill, the arm reaching over it"


# ---------------------------------------------------------------- as a user's solve meets it


def test_the_trap_check_names_a_can_put_behind_the_grill(domain_factory) -> None:
    domain = domain_factory("P6")  # the grill starts at the front of the walled counter
    counter, can, _ = TRAPS["P6"]
    region = domain.problem.spec.region(counter)
    held = _held(domain, _opened(domain), can)
    x, y = se2_to_world((*region.center, region.yaw), *POCKET[0])
    behind = State(
        tuple(sorted({**dict(held.poses), can: ObjectPose.make(x, y, region.top, 0.0)}.items())),
        held.open_doors,
        held.robot,
    )
    assert trap_violations(domain.problem, (held, behind)) == (
        f"step 1: {can} placed on {counter} with beef_grill on it",
    )
    assert trap_violations(domain.problem, (held, held)) == ()


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("name", sorted(TRAPS))
def test_a_solve_puts_nothing_on_the_walled_counter_after_the_grill(
    name, seed, tmp_path, monkeypatch
) -> None:
    out = tmp_path / "result.json"
    code = run_cli(monkeypatch, "solve", name, "--seed", str(seed), "--json", str(out))
    assert code == 0
    record = json.loads(out.read_text())
    assert record["success"], record["termination"]
    check = check_record(load_problem(name), record)
    assert check.reached_goal
    assert check.violations == ()
    assert check.grill_last
