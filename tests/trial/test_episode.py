"""A trial's clock with the reply cache: a query answered from the cache is charged the seconds
its replies took when they were made, so a replayed run shows the time of the run it replays
and runs out of budget when that run did."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from stalm.domain.actions import Pick
from stalm.domain.vocabulary import Vocabulary
from stalm.llm.backends.base import LLMReply, LLMRequest, LLMResponse
from stalm.llm.cache import CachedBackend
from stalm.llm.cache_file import ReplyCache
from stalm.llm.problem_prompt import problem_prompt
from stalm.proposers.language_model import ask_for_task_plans
from stalm.trial.episode import Episode
from tests.planners.llm_reply_doubles import plan_reply

SLOW = 0.4
"""Seconds each call of the slow double takes (a real model takes 10-20 s, §4.3)."""
CACHE_IO = 0.1
"""Reading and writing the cache file: in the first run's measured seconds, not in the
model call's seconds the cache stores."""


class SlowModelBackendDouble:
    """Test double: answers with one fixed reply text after ``seconds`` of wall time."""

    name = "slow-double"
    model = "scripted"
    description = "a test double that takes its time"

    def __init__(self, text: str, seconds: float) -> None:
        self.text = text
        self.seconds = seconds
        self.requests: list[LLMRequest] = []

    def complete(self, request: LLMRequest) -> LLMResponse:
        self.requests.append(request)
        time.sleep(self.seconds)
        replies = tuple(LLMReply(self.text, 50, 20, self.seconds, "stop") for _ in range(request.n))
        return LLMResponse(replies, self.name, self.model)


@pytest.fixture
def asks(problems, tmp_path: Path):
    """A function that sends P2's prompt once through a reply cache over the slow double."""
    problem = problems["P2"]
    inner = SlowModelBackendDouble(plan_reply([Pick("bottle2")]), SLOW)
    backend = CachedBackend(inner, ReplyCache(tmp_path / "replies.sqlite"))
    prompt = problem_prompt(problem, [])

    def ask():
        vocabulary = Vocabulary.from_problem(problem)
        return ask_for_task_plans(backend, vocabulary, prompt, 5, seed=3, constrained=False)

    ask.inner = inner  # type: ignore[attr-defined]
    return ask


def test_a_replayed_query_is_charged_its_original_seconds(problems, domain_factory, asks) -> None:
    problem = problems["P2"]
    fresh = Episode.begin(problem, 60.0)
    made = asks()
    fresh.record_query(made)
    replay = Episode.begin(problem, 60.0)
    deadline = replay.deadline
    replayed = asks()
    replay.record_query(replayed)
    assert len(asks.inner.requests) == 1
    assert not made.from_cache and made.original_seconds == made.seconds >= SLOW
    assert replayed.from_cache and replayed.seconds < SLOW / 2
    assert replayed.original_seconds == pytest.approx(made.seconds, abs=CACHE_IO)
    # the replay's clock counts the original call: same LLM time, deadline moved earlier
    assert replay.clock.proposer == pytest.approx(fresh.clock.proposer, abs=CACHE_IO)
    assert deadline - replay.deadline == pytest.approx(
        made.seconds - replayed.seconds, abs=CACHE_IO
    )
    result = replay.finish(domain_factory("P2"), "stalm", 0, "horizon")
    assert result.times.proposer >= SLOW and result.times.total >= result.times.proposer
    [query] = result.details.queries
    assert query.from_cache is True and query.plans == 5
    assert query.original_seconds == pytest.approx(made.seconds, abs=CACHE_IO)
    assert query.seconds < SLOW / 2
    assert result.details.to_json()["llm_queries_from_cache"] == 1
    fresh_result = fresh.finish(domain_factory("P2"), "stalm", 0, "horizon")
    assert fresh_result.details.queries[0].from_cache is False


def test_a_replayed_query_runs_out_of_the_budget_the_original_ran_out_of(problems, asks) -> None:
    problem = problems["P2"]
    # a budget shorter than the model call: the original trial is out of time after it
    original = Episode.begin(problem, SLOW / 2)
    original.record_query(asks())
    assert original.out_of_time()
    replay = Episode.begin(problem, SLOW / 2)
    replayed = asks()
    assert replayed.from_cache and replayed.seconds < SLOW / 2
    replay.record_query(replayed)
    assert replay.out_of_time(), "the cached reply came fast, but the original took too long"


def test_truncated_plans_are_recorded_in_the_result(problems, domain_factory) -> None:
    from stalm.proposers.protocol import Proposal

    episode = Episode.begin(problems["P2"], 60.0)
    plan = (Pick("bottle2"),)
    episode.record_query(Proposal(plans=(plan, plan), calls=1, truncated=(False, True)))
    result = episode.finish(domain_factory("P2"), "stalm", 0, "horizon")
    details = result.details.to_json()
    assert details["truncated_plans"] == 1
    assert details["llm_queries"][0]["truncated_plans"] == 1


def test_a_trial_records_the_cpu_seconds_it_used_apart_from_wall_time(
    problems, domain_factory
) -> None:
    domain = domain_factory("P2")
    episode = Episode.begin(problems["P2"], 60.0)
    busy_until = time.process_time() + 0.3
    while time.process_time() < busy_until:
        pass
    time.sleep(0.3)  # waiting uses wall time, not CPU time
    times = episode.finish(domain, "stalm", 0, "horizon").times
    assert 0.3 - 0.02 <= times.cpu < 0.3 + 0.25  # os.times counts in 10 ms ticks
    assert times.total >= 0.6
