"""Actions no motion can do are reported, not left to look free (issue 26).

P2 with table1's standing pose moved 0.9 m back from the table: nothing on table1 can be
reached. bottle1 stands there. Its pick is ``CannotPick``; held, its placements on table1 are
``CannotPlace``. ``stalm predicates`` prints them as ``cannot:`` lines, the paper's prompt
leaves them out (a prompt setting adds them), the symbolic proposer's PDDL rules the actions
out, and ``stalm problems --file`` warns that bottle1 can never be moved.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from stalm.domain.actions import Pick
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.pddl import domain_pddl, problem_pddl
from stalm.llm.problem_prompt import goal_literals, problem_prompt
from stalm.llm.prompt import PromptOptions
from stalm.motion.base_motion import BasePlanner
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.literals import GroundLiteral as L
from stalm.predicates.stuck import stuck_objects
from stalm.world.problem import Problem, load_problem, shipped_problems_dir
from stalm.world.scene import Sim
from tests.cli_runner import run_cli

P2_FILE = shipped_problems_dir() / "p2.yaml"


@pytest.fixture(scope="module")
def far_table(tmp_path_factory: pytest.TempPathFactory) -> Problem:
    data = yaml.safe_load(P2_FILE.read_text())
    table1 = next(r for r in data["regions"] if r["name"] == "table1")
    table1["base_pose"] = [3.0, -3.55, 1.570796]  # 1.55 m from the table's centre
    bottle1 = next(o for o in data["objects"] if o["name"] == "bottle1")
    bottle1.update(on="table1", at=[0.0, 0.0])
    path = tmp_path_factory.mktemp("far") / "p2-far-table.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_problem(path)


@pytest.fixture(scope="module")
def literals_of(far_table: Problem):
    sim = Sim(far_table.spec)
    engine = PredicateEngine(far_table, sim, BasePlanner(sim))
    yield engine.compute
    sim.close()


@pytest.fixture(scope="module")
def initial(far_table: Problem, literals_of):
    return literals_of(far_table.initial_state)


def test_a_pick_no_motion_reaches_is_cannot_pick(initial) -> None:
    cache = initial
    assert L("CannotPick", ("bottle1",)) in cache.literals
    assert not any(lit.name == "CannotPick" and lit.args != ("bottle1",) for lit in cache.literals)
    assert "pick bottle1" in cache.unreachable
    assert not any(
        lit.name == "PickOccludedBy" and lit.args[0] == "bottle1" for lit in cache.literals
    )


def test_the_held_objects_impossible_placements_are_cannot_place(
    far_table, literals_of, initial, domain_factory
) -> None:
    p2 = domain_factory("P2")  # bottle1 on table2, where PICK reaches it: a real grasp
    _, picked = p2.sample_and_step(
        p2.problem.initial_state, Pick("bottle1"), np.random.default_rng(0)
    )
    assert picked.feasible
    held = far_table.initial_state.with_changes(
        remove="bottle1", held=picked.state.held, held_yaw_offset=picked.state.held_yaw_offset
    )
    literals = literals_of(held).literals
    assert L("CannotPlace", ("bottle1", "on", "table1")) in literals
    assert L("CannotPlace", ("bottle1", "on", "table2")) not in literals
    # an object at rest is never CannotPlace: another grasp might make its placement possible
    resting = initial.literals
    assert not any(lit.name == "CannotPlace" for lit in resting)


def test_the_papers_prompt_hides_them_and_a_setting_shows_them(far_table, initial) -> None:
    literals = initial.literals
    paper = problem_prompt(far_table, literals).user
    assert "Cannot" not in paper and "cannot be done" not in paper.lower()
    told = problem_prompt(far_table, literals, PromptOptions(cannot_actions=True)).user
    assert "### Cannot be done now ###" in told and "pick(bottle1)" in told
    assert told.index("### Cannot be done now ###") > told.index("(:goal")


def test_the_symbolic_pddl_rules_them_out(far_table, initial) -> None:
    literals = sorted(initial.literals)
    vocabulary = Vocabulary.from_problem(far_table)
    problem = problem_pddl(vocabulary, literals, goal_literals(far_table), "far")
    assert "(CannotPick bottle1)" in problem
    assert "(not (CannotPick ?subject))" in domain_pddl()
    assert "(not (CannotPlace ?subject ?direction ?reference))" in domain_pddl()
    no_occlusion = PromptOptions(occlusion_predicates=False)
    assert "Cannot" not in problem_pddl(vocabulary, literals, [], "far", no_occlusion)


@pytest.mark.slow
def test_predicates_prints_cannot_lines_and_problems_warns(far_table, monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "predicates", far_table.source) == 0
    out = capsys.readouterr().out
    assert "cannot: pick(bottle1)\n" in out and "CannotPick" not in out
    with Sim(far_table.spec) as sim:
        stuck = stuck_objects(far_table, sim, BasePlanner(sim))
    assert set(stuck) == {"bottle1"}
    assert run_cli(monkeypatch, "problems", "--file", far_table.source) == 0
    err = capsys.readouterr().err
    assert "'bottle1' can never be moved: no sampled pick reaches it" in " ".join(err.split())
