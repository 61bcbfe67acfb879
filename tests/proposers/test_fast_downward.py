"""The symbolic proposer: Fast Downward on the predicate PDDL, in place of a language model."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

from stalm import stopping
from stalm.domain.mdp import Domain
from stalm.planners.stalm import StalmPlanner
from stalm.proposers import fast_downward
from stalm.proposers.fast_downward import SymbolicProposer, downward_binary
from stalm.proposers.protocol import ProposalRequest
from stalm.trial.replay import replay_plan
from tests.planners.doubles import plain_settings


def test_fast_downward_plans_from_the_p2_predicates(problems, initial_literals) -> None:
    assert downward_binary().exists()
    problem = problems["P2"]
    proposal = SymbolicProposer().propose(
        ProposalRequest(
            problem, problem.initial_state, frozenset(initial_literals("P2")), 5, seed=0
        )
    )
    assert proposal.plans and len(set(proposal.plans)) == len(proposal.plans)
    domain = Domain.create(problem)
    try:
        for plan in proposal.plans:
            # every plan opens the door first (it occludes everything), moves both bottles out
            # of the salter's way, and ends by placing the salter right of bottle1
            assert str(plan[0]) == "open(kitchen_door)"
            assert str(plan[-1]) == "place(salter, right_of, bottle1)"
            assert {"pick(bottle2)", "pick(bottle3)"} <= {str(a) for a in plan}
            assert all(a in domain.vocabulary.all_discrete_actions() for a in plan)
    finally:
        domain.close()


def test_the_p5_grill_goes_first_symbolically(problems, initial_literals) -> None:
    """It lacks the 3D knowledge as a model does: nothing in the predicates says the grill
    must be placed last, so some plan puts it on counter1 before the cans."""
    problem = problems["P5"]
    plans = (
        SymbolicProposer()
        .propose(
            ProposalRequest(problem, problem.initial_state, frozenset(initial_literals("P5")), 5, 0)
        )
        .plans
    )
    steps = [[str(a) for a in plan] for plan in plans]
    assert any(
        s.index("place(beef_grill, on, counter1)")
        < max(i for i, a in enumerate(s) if a.startswith("place(coke"))
        for s in steps
        if "place(beef_grill, on, counter1)" in s
    )


def test_stalm_with_the_symbolic_proposer_solves_p2(problems) -> None:
    # Seed 1 reaches the goal in two replanning steps with 49 simulations of warm-started UCT;
    # seed 0 takes four steps and about 3x the CPU time.
    planner = StalmPlanner(SymbolicProposer(), plain_settings(30))
    result = planner.solve(problems["P2"], seed=1, time_budget_s=240.0)
    assert result.success and result.counters.llm_calls == 0
    assert replay_plan(problems["P2"], problems["P2"].initial_state, list(result.plan)).reached_goal


def _fast_downward_must_not_run(*args: object) -> None:
    raise AssertionError("Fast Downward ran after the trial's deadline")


def test_past_the_deadline_no_fast_downward_runs_and_no_plan_is_proposed(
    problems, monkeypatch
) -> None:
    monkeypatch.setattr(fast_downward, "translate_task", _fast_downward_must_not_run)
    monkeypatch.setattr(fast_downward, "search_task", _fast_downward_must_not_run)
    problem = problems["P2"]
    proposal = SymbolicProposer().propose(
        ProposalRequest(
            problem, problem.initial_state, frozenset(), 5, seed=0, deadline=time.monotonic() - 1.0
        )
    )
    assert proposal.plans == () and proposal.unparseable == () and proposal.no_plan == ()


def test_fast_downward_cut_short_by_the_deadline_is_a_timeout_not_an_error(
    problems, monkeypatch
) -> None:
    def translator_double_that_times_out(work: Path, time_limit_s: float) -> None:
        time.sleep(time_limit_s)
        raise subprocess.TimeoutExpired("translate", time_limit_s)

    monkeypatch.setattr(fast_downward, "translate_task", translator_double_that_times_out)
    monkeypatch.setattr(fast_downward, "search_task", _fast_downward_must_not_run)
    problem = problems["P2"]
    proposal = SymbolicProposer().propose(
        ProposalRequest(
            problem, problem.initial_state, frozenset(), 5, seed=0, deadline=time.monotonic() + 0.05
        )
    )
    assert proposal.plans == () and proposal.unparseable == () and proposal.no_plan == ()
    # without a deadline the limit that ran out is the proposer's own: no plan from that call,
    # and the reason is kept (test_feedback.py runs the real translator into its limit)
    own = SymbolicProposer(time_limit_s=0.01).propose(
        ProposalRequest(problem, problem.initial_state, frozenset(), 5, 0)
    )
    assert own.plans == () and "time limit" in own.no_plan[0]
    assert own.unparseable == ()  # no reply was misread: the planner found no plan


def test_a_search_without_a_plan_is_named_by_its_exit_code() -> None:
    """Only running out of time or memory is 'giving up' (no rule to blame); an exhausted
    or crashed search is named as such, not as a time limit."""
    why = fast_downward._why

    def run(code: int, output: str = "") -> fast_downward.SearchRun:
        return fast_downward.SearchRun(None, output, code)

    unsolvable = why(run(11, "Task is provably unsolvable."))
    assert "no plan to the goal" in unsolvable
    assert "memory" in why(run(22)) and "memory" in why(run(-9))
    assert "incomplete" in why(run(12))
    assert "exit 33" in why(run(33))
    assert "time limit" in why(run(23))
    assert fast_downward._gave_up([why(run(22))]) and fast_downward._gave_up([why(run(23))])
    assert not any(fast_downward._gave_up([why(run(c))]) for c in (11, 12, 33))


def test_queries_with_consecutive_seeds_share_no_fast_downward_search() -> None:
    """STaLM's k-th proposal of a trial has seed base + k: were the searches' seeds base + k +
    index, a query asked again on the same PDDL would repeat four of its five searches."""
    seeds = [fast_downward.plan_seed(query, index) for query in range(3) for index in range(5)]
    assert len(set(seeds)) == len(seeds)
    assert all(0 <= seed < 2**31 for seed in seeds)
    assert fast_downward.plan_seed(7, 2) == fast_downward.plan_seed(7, 2)
    assert 0 <= fast_downward.plan_seed(-1, 0) < 2**31


def test_fast_downwards_processes_are_started_to_end_with_stalm(
    problems, initial_literals, monkeypatch
) -> None:
    """Its translator and its search are started by ``stopping.run_child``
    (``tests/test_stopping.py`` shows that such a child is killed with its starter), and
    still plan: a worker killed with ``kill -9`` leaves no search running."""
    started: list[str] = []
    real_run_child = stopping.run_child

    def run_child_recording(command, **options):
        started.append("translate" if "fast_downward.translate" in command else command[0])
        return real_run_child(command, **options)

    monkeypatch.setattr(fast_downward.stopping, "run_child", run_child_recording)
    problem = problems["P2"]
    proposal = SymbolicProposer().propose(
        ProposalRequest(problem, problem.initial_state, frozenset(initial_literals("P2")), 1, 0)
    )
    assert proposal.plans
    assert set(started) == {"translate", str(downward_binary())}
