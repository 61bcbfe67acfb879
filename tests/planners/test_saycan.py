"""EP-SayCan: empirical LLM score × affordance, argmax, a history-only prompt, no search."""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.outcome import Infeasibility
from stalm.domain.params import Action
from stalm.llm.backends.base import LLMRequest
from stalm.llm.saycan_prompt import NO_HISTORY, saycan_prompt, task_instruction
from stalm.planners.registry import build_planner
from stalm.planners.saycan import (
    DecisionTally,
    EpSayCanPlanner,
    SayCan,
    SayCanScore,
    affordance,
    occlusion_free,
    saycan_choice,
    saycan_scores,
)
from stalm.predicates.literals import GroundLiteral
from stalm.trial.episode import Episode
from stalm.trial.replay import replay_result_json
from tests.flat_settings import settings_of
from tests.planners.llm_reply_doubles import ScriptedReplyBackendDouble, plan_reply
from tests.planners.test_stalm import P2_PLAN

A, B, C, D = Pick("bottle1"), Pick("bottle2"), Open("kitchen_door"), Pick("salter")


def _score_of(scores: tuple[SayCanScore, ...], action: DiscreteAction) -> SayCanScore:
    return next(s for s in scores if s.action == action)


def saycan_of(backend: ScriptedReplyBackendDouble) -> SayCan:
    """EP-SayCan's part of the planner the API builds for ``backend`` (its decisions)."""
    method = EpSayCanPlanner(backend).start
    assert isinstance(method, SayCan)
    return method


def test_llm_score_is_the_votes_mixed_half_with_uniform_times_affordance() -> None:
    firsts = [A, A, C, D, D]  # D (pick salter) is occluded
    scores = saycan_scores(firsts, 5, [A, B, C, D], lambda a: a != D)
    # 0.5·votes/5 + 0.5/4: A 0.2 + 0.125, B 0 + 0.125, C 0.1 + 0.125, D 0.2 + 0.125
    assert [s.votes for s in scores] == [2, 0, 1, 2]
    assert [s.llm for s in scores] == pytest.approx([0.325, 0.125, 0.225, 0.325])
    assert [s.affordance for s in scores] == [1.0, 1.0, 1.0, 0.0]
    assert [s.score for s in scores] == pytest.approx([0.325, 0.125, 0.225, 0.0])
    assert saycan_choice(scores, np.random.default_rng(0)) == A


def test_an_affordable_action_no_reply_named_still_scores_through_the_uniform_part() -> None:
    # every reply names the occluded pick; the affordable actions share the uniform half
    scores = saycan_scores([D] * 5, 5, [A, C, D], lambda a: a != D)
    assert [s.score for s in scores] == pytest.approx([1 / 6, 1 / 6, 0.0])
    assert saycan_choice(scores, np.random.default_rng(0)) in {A, C}
    # with no uniform part the votes alone decide, and nothing affordable was voted for
    votes_only = saycan_scores([D] * 5, 5, [A, C, D], lambda a: a != D, uniform_weight=0.0)
    assert saycan_choice(votes_only, np.random.default_rng(0)) is None


def test_unreadable_replies_count_in_the_denominator_and_unknown_firsts_are_dropped() -> None:
    place = Place("salter", "on", "table2")  # not a candidate: its precondition is false
    scores = saycan_scores([C, place], 5, [A, C], lambda a: True, uniform_weight=0.0)
    # one usable vote of five: C gets 0.2 before renormalising the missing mass away
    assert _score_of(scores, C).votes == 1 and _score_of(scores, C).llm == pytest.approx(1.0)
    assert _score_of(scores, A).llm == 0.0
    assert {s.action for s in scores} == {A, C}
    mixed = saycan_scores([C, place], 5, [A, C], lambda a: True)
    # (0.5·0.2 + 0.25, 0.25) = (0.35, 0.25), renormalised over 0.6
    assert _score_of(mixed, C).llm == pytest.approx(0.35 / 0.6)


def test_precondition_violating_and_occluded_actions_get_zero_and_may_leave_nothing() -> None:
    scores = saycan_scores([D, D, D, B, B], 5, [B, D], lambda a: False)
    assert all(s.score == 0.0 for s in scores)
    assert saycan_choice(scores, np.random.default_rng(0)) is None


def test_ties_are_broken_by_the_generator_reproducibly_and_exclusion_takes_the_next_best() -> None:
    scores = saycan_scores([A, A, C, C, B], 5, [A, B, C], lambda a: True)
    picks = {saycan_choice(scores, np.random.default_rng(seed)) for seed in range(20)}
    assert picks == {A, C}
    assert all(
        saycan_choice(scores, np.random.default_rng(s))
        == saycan_choice(scores, np.random.default_rng(s))
        for s in range(5)
    )
    assert saycan_choice(scores, np.random.default_rng(0), excluded={A}) == C
    assert saycan_choice(scores, np.random.default_rng(0), excluded={A, C}) == B


def test_occlusion_predicates_remove_occluded_picks_and_places_only() -> None:
    free = occlusion_free(
        [
            GroundLiteral("PickOccludedBy", ("salter", "bottle2")),
            GroundLiteral("PlaceOccludedBy", ("salter", "on", "table2", "bottle1")),
            GroundLiteral("AtPosition", ("bottle1", "on", "table2")),
        ]
    )
    assert not free(Pick("salter")) and free(Pick("bottle1"))
    assert not free(Place("salter", "on", "table2")) and free(Place("salter", "on", "counter1"))
    assert free(Open("kitchen_door"))


def test_affordance_in_p2s_initial_state_uses_preconditions_and_computed_occlusions(
    domain_factory, initial_literals
) -> None:
    domain = domain_factory("P2")
    afford = affordance(domain, domain.problem.initial_state, initial_literals("P2"))
    assert afford(Open("kitchen_door")) and afford(Pick("bottle1"))
    assert not afford(Pick("salter")), "the bottles and the closed door occlude the salter"
    assert not afford(Pick("bottle2")), "the closed door occludes bottle2"
    assert not afford(Place("salter", "on", "table2")), "the hand holds nothing"


def test_prompt_has_the_instruction_names_and_history_but_no_predicates(problems) -> None:
    problem = problems["P2"]
    first = saycan_prompt(problem, [])
    assert task_instruction(problem) == "Put salter on table2 and salter right_of bottle1."
    assert task_instruction(problem) in first.user
    for name in ("salter", "bottle1", "kitchen_door", "table2", "counter1"):
        assert name in first.user
    assert NO_HISTORY in first.user
    for predicate in (
        "PickOccludedBy",
        "PlaceOccludedBy",
        "AtPosition",
        "HandAvailable",
        "IsClosed",
    ):
        assert predicate not in first.user and predicate not in first.system
    assert "plan = [" in first.system
    later = saycan_prompt(problem, [Open("kitchen_door"), Pick("bottle2")])
    assert "1. ('open', 'kitchen_door')\n2. ('pick', 'bottle2')" in later.user
    assert NO_HISTORY not in later.user


def _history_length(request: LLMRequest) -> int:
    section = request.user.split("### Actions executed so far ###", 1)[1]
    return len(re.findall(r"^\d+\. \(", section, flags=re.MULTILINE))


def test_replies_naming_only_an_occluded_action_still_let_an_affordable_one_run(problems) -> None:
    # every reply starts with picking the salter, which the door and bottles occlude
    backend = ScriptedReplyBackendDouble(
        queue=[[plan_reply([Pick("salter"), Open("kitchen_door")])]]
    )
    planner = saycan_of(backend)
    episode = Episode.begin(problems["P2"], 120.0)
    tally = DecisionTally()
    domain = KappaDomainDouble([D, A, C], stuck=set())
    chosen = planner.decide(
        domain, episode, _SALTER_OCCLUDED, 0, 0, np.random.default_rng(0), tally
    )  # type: ignore[arg-type]
    assert chosen is not None and chosen.discrete in {A, C}
    assert tally.queries == 1 and tally.zero_score_queries == 0
    assert tally.decisions[0].to_json()["voted"] == [
        [["pick", "salter"], 5, pytest.approx(0.5 + 0.5 / 3), 0.0]
    ]


def test_votes_only_asks_again_then_ends_as_no_progress(problems) -> None:
    backend = ScriptedReplyBackendDouble(
        queue=[[plan_reply([Pick("salter"), Open("kitchen_door")])]]
    )
    planner = EpSayCanPlanner(backend)
    # votes only: a constant of the method's own, which the settings tree does not hold
    saycan = planner.start
    assert isinstance(saycan, SayCan)
    votes_only = replace(saycan, constants=replace(saycan.constants, uniform_weight=0.0))
    planner = replace(planner, start=votes_only)
    result = planner.solve(problems["P2"], seed=0, time_budget_s=120.0)
    assert result.termination == "no_progress" and not result.success and result.plan == ()
    assert result.counters.llm_calls == 3 and len(backend.requests) == 3
    seeds = [r.seed for r in backend.requests]
    assert len(set(seeds)) == 3, "each re-ask uses the next derived seed"
    assert all(r.n == 5 and r.temperature == 1.0 for r in backend.requests)
    decisions = result.details.method.decisions
    assert [d.chosen for d in decisions] == [None, None, None]
    assert decisions[0].to_json()["first_actions"] == [["pick", "salter"]] * 5


def test_with_nothing_affordable_left_the_trial_ends_without_asking_again(problems) -> None:
    backend = ScriptedReplyBackendDouble(queue=[[plan_reply([A])]])
    domain = KappaDomainDouble([A, D], stuck={A})  # A has no κ, D is occluded
    planner = saycan_of(backend)
    tally = DecisionTally()
    episode = Episode.begin(problems["P2"], 60.0)
    chosen = planner.decide(
        domain, episode, _SALTER_OCCLUDED, 0, 0, np.random.default_rng(0), tally
    )  # type: ignore[arg-type]
    assert chosen is None and len(backend.requests) == 1
    assert domain.draws == [A, A, A] and tally.zero_score_queries == 1


_SALTER_OCCLUDED = [GroundLiteral("PickOccludedBy", ("salter", "bottle2"))]


@pytest.mark.slow
def test_saycan_solves_p2_when_the_replies_name_the_right_next_action(problems) -> None:
    def responder(request: LLMRequest) -> list[str]:
        done = _history_length(request)
        return [plan_reply(P2_PLAN[done:])]

    backend = ScriptedReplyBackendDouble(responder=responder)
    result = EpSayCanPlanner(backend).solve(problems["P2"], seed=0, time_budget_s=240.0)
    assert result.success and result.termination == "goal", result.details
    assert [a.discrete for a in result.plan] == list(P2_PLAN)
    # one decision per executed action; the history in the prompt grows by one each time
    assert [_history_length(r) for r in backend.requests] == list(range(len(P2_PLAN)))
    assert result.counters.llm_calls == len(P2_PLAN)
    data = json.loads(json.dumps(result.to_json()))
    assert data["success"] is True and data["termination"] == "goal"
    assert data["planner"] == "ep-saycan" and data["details"]["zero_score_queries"] == 0
    assert replay_result_json(problems["P2"], data).reached_goal


def test_the_registry_builds_ep_saycan_with_the_configured_batch() -> None:
    planner = build_planner("ep-saycan", settings_of(llm="embedded", batch=3, cache_mode="off"))
    assert isinstance(planner.start, SayCan)
    assert planner.name == "ep-saycan" and planner.start.settings.search.batch == 3


class KappaDomainDouble:
    """A domain double: every action is legal; ψ never finds κ for the actions in ``stuck``."""

    def __init__(self, actions: list[DiscreteAction], stuck: set[DiscreteAction]) -> None:
        self.actions = tuple(actions)
        self.stuck = stuck
        self.draws: list[DiscreteAction] = []

    def legal_actions(self, state: object) -> tuple[DiscreteAction, ...]:
        return self.actions

    def precondition_failure(self, state: object, action: DiscreteAction) -> str | None:
        return None

    def sample(self, state: object, action: DiscreteAction, rng: object) -> object:
        self.draws.append(action)
        if action in self.stuck:
            return Infeasibility("no_placement", "test double: no κ")
        return Action(action, None)  # type: ignore[arg-type]


def test_an_action_without_feasible_kappa_is_excluded_after_three_draws_and_the_next_best_runs(
    problems,
) -> None:
    # three replies start with pick(bottle1), two with open; ψ never finds κ for pick(bottle1)
    backend = ScriptedReplyBackendDouble(queue=[[plan_reply([A])] * 3 + [plan_reply([C])] * 2])
    domain = KappaDomainDouble([A, C], stuck={A})
    planner = saycan_of(backend)
    episode = Episode.begin(problems["P2"], 60.0)
    tally = DecisionTally()
    chosen = planner.decide(domain, episode, [], 0, 0, np.random.default_rng(0), tally)  # type: ignore[arg-type]
    assert chosen is not None and chosen.discrete == C
    assert domain.draws == [A, A, A, C]
    assert tally.kappa_failures == 1 and tally.queries == 1
