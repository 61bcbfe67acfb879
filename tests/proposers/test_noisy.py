"""The noisy proposer: Figure 5's errors made on purpose in hand-built P2, P5 and P6 plans.

The literals are written by hand (the occluders the predicate engine reports for the initial
states: the closed door in front of everything in the kitchen, P2's bottles boxing in the
salter, P6's grill in front of its walled counter), so these tests need no simulator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict

import pytest

from stalm.domain.actions import Open, Pick, Place
from stalm.domain.outcome import Infeasibility
from stalm.errors import StalmError
from stalm.planners.registry import asks_model, build_planner, resolve
from stalm.planners.stalm import StalmPlanner, StalmSteps
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.fast_downward import SymbolicProposer
from stalm.proposers.feedback import FailedStep
from stalm.proposers.noisy import NoisyProposer, injected_records, noise_rng
from stalm.proposers.plan_noise import (
    PlanContext,
    corrupt_plans,
    crowded_reorders,
    partial_goals,
    precondition_violations,
)
from stalm.proposers.protocol import Proposal, ProposalRequest
from stalm.search import TaskPlan
from stalm.search.concretize import ConcretePlan
from stalm.settings.io import with_overrides
from stalm.settings.tree import RunSettings
from stalm.world.problem import Problem
from tests.planners.test_stalm import P2_PLAN, P6_PLAN

P5_PLAN = (
    Open("kitchen_door"),
    Pick("coke"),
    Place("coke", "on", "counter1"),
    Pick("sprite"),
    Place("sprite", "on", "counter1"),
    Pick("beef_grill"),
    Place("beef_grill", "on", "counter1"),
)
"""P5 solved as Figure 6 says: the cans first, the grill last (coke is behind the grill)."""


def _literals(*text: str) -> list[GroundLiteral]:
    literals = []
    for item in text:
        name, _, rest = item.partition("(")
        literals.append(GroundLiteral(name, tuple(a.strip() for a in rest.rstrip(")").split(","))))
    return literals


P2_LITERALS = _literals(
    "AtPosition(salter, on, counter2)",
    "AtPosition(bottle1, on, table2)",
    "AtPosition(bottle2, on, counter2)",
    "AtPosition(bottle3, on, counter2)",
    "PickOccludedBy(salter, bottle2)",
    "PickOccludedBy(salter, bottle3)",
    "PickOccludedBy(salter, kitchen_door)",
    "PickOccludedBy(bottle2, kitchen_door)",
    "PickOccludedBy(bottle3, kitchen_door)",
)
P5_LITERALS = _literals(
    "AtPosition(coke, on, counter2)",
    "AtPosition(beef_grill, on, counter2)",
    "AtPosition(sprite, on, counter3)",
    "PickOccludedBy(coke, beef_grill)",
    "PickOccludedBy(coke, kitchen_door)",
    "PickOccludedBy(beef_grill, kitchen_door)",
)
P6_LITERALS = _literals(
    "AtPosition(beef_grill, on, counter2)",
    "AtPosition(coke, on, counter1)",
    "AtPosition(wine, on, table1)",
    "PickOccludedBy(coke, kitchen_door)",
    "PickOccludedBy(beef_grill, kitchen_door)",
    "PlaceOccludedBy(coke, on, counter2, beef_grill)",
    "PlaceOccludedBy(wine, on, counter2, beef_grill)",
)


@pytest.fixture
def contexts(problems: dict[str, Problem]) -> dict[str, PlanContext]:
    return {
        "P2": PlanContext.of(problems["P2"], P2_LITERALS),
        "P5": PlanContext.of(problems["P5"], P5_LITERALS),
        "P6": PlanContext.of(problems["P6"], P6_LITERALS),
    }


def _text(plan: Sequence[object]) -> list[str]:
    return [str(step) for step in plan]


def test_a_precondition_violation_drops_a_step_that_clears_the_way(contexts) -> None:
    variants = precondition_violations(P2_PLAN, contexts["P2"])
    dropped = [sorted(set(_text(P2_PLAN)) - set(_text(v))) for v in variants]
    assert dropped == [
        ["open(kitchen_door)"],
        ["pick(bottle2)", "place(bottle2, on, counter1)"],
        ["pick(bottle3)", "place(bottle3, on, counter1)"],
    ]
    # the salter's placement is the goal's: never the dropped step
    assert all(v[-1] == Place("salter", "right_of", "bottle1") for v in variants)
    # P6: the door, or the grill's first move (it is in the way of the cans' placements);
    # never the grill's last move, which is its goal placement
    p6 = precondition_violations(P6_PLAN, contexts["P6"])
    assert [len(v) for v in p6] == [8, 7]
    assert p6[1] == (P6_PLAN[0], *P6_PLAN[3:])


def test_lack_of_3d_understanding_puts_the_grill_first(contexts) -> None:
    [p5] = crowded_reorders(P5_PLAN, contexts["P5"])
    # after the door it needs, before the cans: "the grill to the goal first"
    assert _text(p5) == [
        "open(kitchen_door)",
        "pick(beef_grill)",
        "place(beef_grill, on, counter1)",
        "pick(coke)",
        "place(coke, on, counter1)",
        "pick(sprite)",
        "place(sprite, on, counter1)",
    ]
    [p6] = crowded_reorders(P6_PLAN, contexts["P6"])
    # the grill's return to counter2 comes before the cans, after its own first move
    assert p6 == (*P6_PLAN[:3], *P6_PLAN[7:], *P6_PLAN[3:7])
    assert sorted(_text(p6)) == sorted(_text(P6_PLAN))
    # reordering bottles of about one size is no 3D mistake: the kind does not apply to P2
    assert crowded_reorders(P2_PLAN, contexts["P2"]) == []


def test_the_grill_is_not_brought_before_what_clears_its_way(problems) -> None:
    """Brought forward, it stays after what its own pick needs (invented occluders here), so
    the plan's predicates still hold and only the geometry is wrong."""
    behind_coke = [*P5_LITERALS, *_literals("PickOccludedBy(beef_grill, coke)")]
    [variant] = crowded_reorders(P5_PLAN, PlanContext.of(problems["P5"], behind_coke))
    assert _text(variant)[1:5] == [
        "pick(coke)",
        "place(coke, on, counter1)",
        "pick(beef_grill)",
        "place(beef_grill, on, counter1)",
    ]
    # behind the sprite too: no placement into counter1 is left for it to go before
    behind_both = [*behind_coke, *_literals("PickOccludedBy(beef_grill, sprite)")]
    assert crowded_reorders(P5_PLAN, PlanContext.of(problems["P5"], behind_both)) == []


def test_a_partially_achieved_goal_cuts_before_the_last_goal_objects(contexts) -> None:
    p5 = partial_goals(P5_PLAN, contexts["P5"])
    assert [len(v) for v in p5] == [5, 3, 1]  # one, two or all three goal objects left out
    assert all(v == P5_PLAN[: len(v)] for v in p5)
    assert partial_goals(P2_PLAN, contexts["P2"]) == [P2_PLAN[:5]]
    # a plan whose only step is a goal placement cannot be cut to anything
    assert partial_goals((Pick("salter"), Place("salter", "on", "table2")), contexts["P2"]) == []


PLANS = {"P2": P2_PLAN, "P5": P5_PLAN, "P6": P6_PLAN}


def test_rate_zero_changes_nothing_and_rate_one_corrupts_every_plan(contexts) -> None:
    weights = (1.0, 1.0, 1.0)
    for name, plan in PLANS.items():
        batch = [plan] * 8
        same, labels = corrupt_plans(batch, contexts[name], 0.0, weights, noise_rng(3))
        assert same == tuple(batch) and set(labels) == {"clean"}
        changed, labels = corrupt_plans(batch, contexts[name], 1.0, weights, noise_rng(3))
        assert all(c != plan for c in changed), name
        assert set(labels) <= {
            "precondition_violation",
            "lack_of_3d_understanding",
            "partially_achieved_goal",
        }
    # over many plans each applicable kind is drawn (3D does not apply to P2)
    _, labels = corrupt_plans([P6_PLAN] * 60, contexts["P6"], 1.0, weights, noise_rng(0))
    assert set(labels) == {
        "precondition_violation",
        "lack_of_3d_understanding",
        "partially_achieved_goal",
    }
    _, labels = corrupt_plans([P2_PLAN] * 60, contexts["P2"], 1.0, weights, noise_rng(0))
    assert set(labels) == {"precondition_violation", "partially_achieved_goal"}


def test_the_same_seed_gives_the_same_corruptions_and_rates_nest(contexts) -> None:
    batch = [P6_PLAN] * 40
    runs = {
        rate: corrupt_plans(batch, contexts["P6"], rate, (1.0, 1.0, 1.0), noise_rng(11))
        for rate in (0.25, 0.5, 0.75)
    }
    again = corrupt_plans(batch, contexts["P6"], 0.5, (1.0, 1.0, 1.0), noise_rng(11))
    assert again == runs[0.5]
    assert corrupt_plans(batch, contexts["P6"], 0.5, (1.0, 1.0, 1.0), noise_rng(12)) != again
    # a plan corrupted at a lower rate is corrupted the same way at a higher one
    for low, high in ((0.25, 0.5), (0.5, 0.75)):
        for i, label in enumerate(runs[low][1]):
            if label != "clean":
                assert runs[high][1][i] == label and runs[high][0][i] == runs[low][0][i]
    shares = [sum(label != "clean" for label in runs[r][1]) for r in (0.25, 0.5, 0.75)]
    assert shares == sorted(shares) and 0 < shares[0] < shares[2] < 40


def test_weights_choose_the_kind_and_a_plan_no_kind_applies_to_stays(contexts) -> None:
    _, labels = corrupt_plans([P6_PLAN] * 20, contexts["P6"], 1.0, (0, 1, 0), noise_rng(0))
    assert set(labels) == {"lack_of_3d_understanding"}
    plans, labels = corrupt_plans([P2_PLAN] * 5, contexts["P2"], 1.0, (0, 1, 0), noise_rng(0))
    assert plans == (P2_PLAN,) * 5 and set(labels) == {"inapplicable"}


class InnerDouble:
    """Returns the same plans whatever it is asked (tests only)."""

    name = "inner-test-double"
    takes_feedback = True

    def __init__(self, plans: Sequence[tuple]) -> None:
        self.plans = tuple(plans)
        self.feedback: Sequence[FailedStep] = ()

    def propose(self, request: ProposalRequest) -> Proposal:
        self.feedback = request.feedback
        return Proposal(plans=self.plans[: request.n], calls=0, seconds=0.01)


def test_the_noisy_proposer_wraps_its_inner_proposer(problems) -> None:
    problem = problems["P6"]
    inner = InnerDouble([P6_PLAN] * 5)
    state = problem.initial_state
    clean = NoisyProposer(inner, rate=0.0).propose(
        ProposalRequest(problem, state, frozenset(P6_LITERALS), 5, seed=4)
    )
    assert clean.plans == inner.plans and clean.injected == ("clean",) * 5
    noisy = NoisyProposer(inner, rate=1.0)
    first = noisy.propose(ProposalRequest(problem, state, frozenset(P6_LITERALS), 5, seed=4))
    assert first == noisy.propose(
        ProposalRequest(problem, state, frozenset(P6_LITERALS), 5, seed=4)
    )
    assert all(plan != P6_PLAN for plan in first.plans) and "clean" not in first.injected
    assert first.seconds == 0.01 and first.calls == 0
    # its name says what it is: a degraded proposer around another, no model
    assert noisy.name == "noisy:1:inner-test-double"
    assert noisy.record(()).to_json()["weights"]["partially_achieved_goal"] == 1.0
    why = Infeasibility("no_placement", "no room on counter2")
    failed = (FailedStep(P6_PLAN, 4, why, (), (), frozenset()),)
    noisy.propose(
        ProposalRequest(problem, state, frozenset(P6_LITERALS), 5, seed=4, feedback=tuple(failed))
    )
    assert inner.feedback == failed
    # it passes feedback on only to an inner proposer that reads it
    assert noisy.takes_feedback
    inner.takes_feedback = False
    assert not noisy.takes_feedback
    with pytest.raises(StalmError, match="inner-test-double takes no feedback"):
        noisy.propose(
            ProposalRequest(problem, state, frozenset(P6_LITERALS), 5, seed=4, feedback=failed)
        )
    with pytest.raises(StalmError, match="rate must be in"):
        NoisyProposer(inner, rate=1.5)


def test_the_record_pairs_each_injected_kind_with_the_classified_one() -> None:
    def plan(index: int, failure: str | None) -> ConcretePlan:
        return ConcretePlan(index, TaskPlan((Open("kitchen_door"),)), (), failure is None, failure)  # type: ignore[arg-type]

    concretized = [
        plan(0, "precondition_violation"),
        plan(1, "partially_achieved_goal"),
        plan(2, None),
    ]
    injected = ("precondition_violation", "clean", "lack_of_3d_understanding", "clean")
    records = injected_records(3, 1, injected, concretized, ())
    assert [(r.injected, r.kind) for r in records] == [
        ("precondition_violation", "precondition_violation"),
        ("clean", "partially_achieved_goal"),
        ("lack_of_3d_understanding", "reached_goal"),
        ("clean", "not_tried"),  # Concretize stopped at the goal plan before it
    ]
    assert {(r.step, r.round) for r in records} == {(3, 1)}


def test_the_settings_build_the_noisy_proposer_without_a_model() -> None:
    settings = with_overrides(
        RunSettings(),
        [
            "proposer.kind=noisy",
            "proposer.noise.rate=0.25",
            "proposer.noise.weights=[1, 2, 0]",
            "prompt.occlusion_predicates=false",
        ],
    )
    planner = build_planner("stalm", settings)
    assert isinstance(planner.start, StalmSteps)
    proposer = planner.start.proposer
    assert isinstance(proposer, NoisyProposer) and isinstance(proposer.inner, SymbolicProposer)
    assert (proposer.rate, proposer.weights) == (0.25, (1.0, 2.0, 0.0))
    assert not asks_model("stalm", settings) and not asks_model("stalm-no-uct", settings)
    # feedback is off by default (the point is to see the tree repair the plans); the
    # occlusion literals are computed whatever the prompt says: the corruptions need them
    resolved = resolve("stalm", settings)
    assert (resolved.execution.feedback, resolved.execution.backtracks) == (False, 0)
    assert planner.start.settings.feedback() is False
    assert planner.occlusion
    on = with_overrides(settings, ["execution.feedback=true"])
    assert build_planner("stalm", on).start.settings.feedback() is True
    llm = with_overrides(
        settings, ["proposer.noise.inner=llm", "llm.backend=http://127.0.0.1:9/v1#m"]
    )
    assert asks_model("stalm", llm)
    assert build_planner("stalm", llm).start.proposer.inner.name.startswith("llm:")


def test_a_stalm_trial_records_what_was_injected(problems) -> None:
    """A short STaLM trial on P2 (horizon 1, two simulations): every plan the noisy proposer
    offered is in ``details['noise']`` with its injected and its classified kind."""
    from tests.planners.doubles import ScriptedSuffixProposer, plain_settings

    problem = Problem(problems["P2"].spec.model_copy(update={"horizon": 1}), problems["P2"].source)
    inner = ScriptedSuffixProposer(problem, P2_PLAN)
    try:
        noisy = NoisyProposer(inner, rate=1.0, weights=(1.0, 0.0, 0.0))
        settings = plain_settings(2)
        result = StalmPlanner(noisy, settings).solve(problem, seed=5, time_budget_s=600.0)
    finally:
        inner.close()
    noise = result.details.method.noise
    assert noise.rate == 1.0 and noise.inner == "scripted-test-double"
    assert result.details.proposer == "noisy:1:scripted-test-double"
    entries = [asdict(plan) for plan in noise.plans]
    # one proposal: the scripted suffixes that can start now (the whole plan, from each pick)
    assert [e["index"] for e in entries] == list(range(len(entries))) and len(entries) >= 3
    assert {(e["step"], e["round"]) for e in entries} == {(0, 0)}
    injected = [e["injected"] for e in entries]
    assert injected[0] == "precondition_violation"
    assert set(injected) <= {"precondition_violation", "inapplicable"}
    # nothing clears the way for the suffix that starts at the salter's pick
    assert injected[-1] == "inapplicable"
    tried = [e for e in entries if e["kind"] != "not_tried"]
    assert sum(result.llm_plan_failures.values()) == sum(e["kind"] != "reached_goal" for e in tried)
