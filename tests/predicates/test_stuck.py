"""Which goal the objects that can never move make unreachable (issue 46, item 11): a goal
atom not true at the start whose every object is stuck can never come true."""

from __future__ import annotations

from pathlib import Path

import yaml

from stalm.motion.base_motion import BasePlanner
from stalm.predicates.stuck import goal_unreachable, stuck_objects, unreachable_goal
from stalm.world.problem import Problem, load_problem
from stalm.world.scene import Sim


def _with_goal(problems: dict[str, Problem], tmp_path: Path, goal: list[list[str]]) -> Problem:
    data = yaml.safe_load(Path(problems["P2"].source).read_text())
    data["goal"] = goal
    path = tmp_path / "goal.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_problem(path)


def test_an_atom_whose_objects_are_all_stuck_is_unreachable(problems, tmp_path) -> None:
    p2 = problems["P2"]  # salter on table2, salter right_of bottle1
    assert unreachable_goal(p2, {}) is None
    assert unreachable_goal(p2, {"bottle1": "why"}) is None  # the salter can still move
    assert unreachable_goal(p2, {"salter": "no pick"}) == (
        "goal[0] ('salter' on 'table2'): 'salter' can never be moved: no pick"
    )
    assert unreachable_goal(p2, {"salter": "a", "bottle1": "b"}).startswith("goal[0]")


def test_an_atom_already_true_needs_no_move(problems, tmp_path) -> None:
    # bottle1 starts on table2 (P2): its goal needs nothing moved, stuck or not
    problem = _with_goal(problems, tmp_path, [["bottle1", "on", "table2"]])
    assert unreachable_goal(problem, {"bottle1": "why"}) is None
    assert goal_unreachable(problem) is None  # nothing to check: no scene is built


def test_the_check_samples_only_the_objects_named_and_says_how_far_it_is(problems) -> None:
    p2 = problems["P2"]
    heard: list[tuple[int, int]] = []
    with Sim(p2.spec) as sim:
        stuck = stuck_objects(
            p2, sim, BasePlanner(sim), names={"salter"}, progress=lambda *n: heard.append(n)
        )
    assert stuck == {}
    assert heard == [(0, 1), (1, 1)]
    assert goal_unreachable(p2) is None  # P2 is solvable


def test_a_reference_is_checked_only_where_its_subject_is_stuck(problems, monkeypatch) -> None:
    from stalm.predicates import stuck as stuck_module

    asked: list[set[str]] = []
    real = stuck_module.stuck_objects

    def recording(problem, sim, base_planner, settings=None, *, names=None, progress=None):
        asked.append(set(names))
        found = real(problem, sim, base_planner, settings, names=names, progress=progress)
        return found | ({"salter": "made stuck"} if "salter" in names else {})

    monkeypatch.setattr(stuck_module, "stuck_objects", recording)
    why = goal_unreachable(problems["P2"])
    assert asked == [{"salter"}, {"bottle1"}]  # bottle1 asked about once salter is stuck
    assert why == "goal[0] ('salter' on 'table2'): 'salter' can never be moved: made stuck"
