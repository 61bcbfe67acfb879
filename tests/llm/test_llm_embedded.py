"""The embedded backend running the packaged SmolLM2 model for real (small token budgets)."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterator

import pytest

from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.backends import EmbeddedBackend, LLMRequest, OutputConstraint, embedded
from stalm.llm.backends.embedded_models import locate_embedded_model
from stalm.llm.constraints import ConstraintLimits, build_constraint, build_gbnf
from stalm.llm.reply_parser import parse_reply

SYSTEM = (
    "You are an expert proficient in PDDL and planning actions for a problem. Your response "
    "should follow this template:\n## Possible Challenges for unachieved goals based on current "
    "state ##\n\n## Plan for unachieved goals ## plan = [('action_type', 'args_1', 'args_2',...), ]"
)
USER = (
    "(:objects coke - movable_object sprite - movable_object kitchen_door - openable "
    "counter1 - region counter2 - region )\n(:init [('HandAvailable', ''), ('AtPosition', 'coke', "
    "'on', 'counter1'), ('PickOccludedBy', 'coke', 'kitchen_door')] )\n"
    "(:goal (and (AtPosition coke on counter2) ) )\nGenerate a plan to achieve the goals from init."
)
VOCABULARY = Vocabulary(
    movables=("coke", "sprite"), regions=("counter1", "counter2"), doors=("kitchen_door",)
)
SMALL = ConstraintLimits(max_challenge_lines=2, max_line_chars=60, max_steps=4)
TEMPLATE = re.compile(
    r"## Possible Challenges for unachieved goals based on current state ##\n"
    r"(?:[1-9]\. [^\n#]{1,60}\n){1,2}\n## Plan for unachieved goals ##\nplan = \[.*\]\Z",
    re.DOTALL,
)


@pytest.fixture(scope="module")
def backend() -> Iterator[EmbeddedBackend]:
    yield EmbeddedBackend(n_ctx=1024)


def test_the_packaged_model_file_is_found() -> None:
    path = locate_embedded_model("smollm2")
    assert path.name == "SmolLM2-135M-Instruct.Q4_1.gguf" and path.stat().st_size > 50_000_000


def test_unknown_embedded_model_is_a_user_error() -> None:
    with pytest.raises(StalmError, match="smollm2, gemma3-270m"):
        EmbeddedBackend("llama-70b")


@pytest.mark.slow
def test_constrained_batch_follows_the_template(backend: EmbeddedBackend) -> None:
    request = LLMRequest(
        system=SYSTEM,
        user=USER,
        n=3,
        temperature=1.0,
        max_tokens=200,
        seed=11,
        constraint=build_constraint(VOCABULARY, SMALL),
    )
    response = backend.complete(request)
    assert (response.backend, response.model) == ("embedded", "SmolLM2-135M-Instruct (Q4_1)")
    assert len(response.replies) == 3
    for reply in response.replies:
        assert reply.finish_reason == "stop"
        assert TEMPLATE.match(reply.text), reply.text
        parsed = parse_reply(reply.text, VOCABULARY)
        assert parsed.reason is None and 1 <= len(parsed.plan) <= 4, reply.text
    # The prompt is evaluated once for the batch and counted once.
    assert response.replies[0].prompt_tokens > 100
    assert [r.prompt_tokens for r in response.replies[1:]] == [0, 0]
    assert all(r.completion_tokens > 0 for r in response.replies)


@pytest.mark.slow
def test_sample_i_uses_seed_plus_i(backend: EmbeddedBackend) -> None:
    request = LLMRequest(
        system="Answer briefly.", user="Name a fruit.", n=3, max_tokens=12, seed=40
    )
    batch = backend.complete(request)
    alone = backend.complete(dataclasses.replace(request, n=1, seed=42))
    assert alone.texts[0] == batch.texts[2]
    assert backend.complete(request).texts == batch.texts


@pytest.mark.slow
def test_max_tokens_cuts_the_reply(backend: EmbeddedBackend) -> None:
    request = LLMRequest(system="s", user="Count from one to fifty in words.", max_tokens=4, seed=0)
    reply = backend.complete(request).replies[0]
    assert (reply.finish_reason, reply.completion_tokens) == ("length", 4)


@pytest.mark.slow
def test_a_prompt_longer_than_the_context_is_a_user_error() -> None:
    small = EmbeddedBackend(n_ctx=128)
    with pytest.raises(StalmError, match="does not fit") as refused:
        small.complete(LLMRequest(system="s", user="word " * 400, max_tokens=4))
    message = str(refused.value)
    # names the prompt's size, the context and what to use instead, before loading weights
    assert re.search(r"the prompt is \d{3} tokens", message) and "context of 128 tokens" in message
    assert "--proposer symbolic" in message and "\n" not in message
    assert small._llama is None


@pytest.mark.slow
def test_grammars_parse_in_llama_cpp_and_a_bad_one_is_an_error(
    backend: EmbeddedBackend, p5_vocabulary: Vocabulary
) -> None:
    for vocabulary in (
        p5_vocabulary,
        Vocabulary(movables=("cup",), regions=("table",), doors=()),
        Vocabulary(movables=("a", "b"), regions=(), doors=("door",)),
    ):
        request = LLMRequest(
            system="s",
            user="plan",
            max_tokens=1,
            seed=0,
            constraint=OutputConstraint("t", build_gbnf(vocabulary), "{}"),
        )
        backend.complete(request)  # would raise StalmError on a grammar llama.cpp rejects
    broken = OutputConstraint("t", "root ::= ( unclosed", "{}")
    with pytest.raises(StalmError, match="cannot parse the output grammar"):
        backend.complete(LLMRequest(system="s", user="u", max_tokens=1, constraint=broken))


def test_a_deadline_stops_sampling_and_cut_replies_are_not_cached(
    backend: EmbeddedBackend, tmp_path
) -> None:
    import time

    from stalm.llm.cache import CachedBackend
    from stalm.llm.cache_file import ReplyCache

    request = LLMRequest(system="You answer briefly.", user="Say hi.", n=3, max_tokens=8, seed=1)
    passed = dataclasses.replace(request, deadline=time.monotonic() - 1.0)
    assert backend.complete(passed).replies == ()
    cache = ReplyCache(tmp_path / "r.sqlite")
    cached = CachedBackend(backend, cache)
    assert cached.complete(passed).replies == ()
    assert len(cache) == 0
    # a generous deadline changes nothing, and the replies are cached under the usual keys
    roomy = dataclasses.replace(request, deadline=time.monotonic() + 600)
    assert cached.complete(roomy).texts == backend.complete(request).texts
    assert len(cache) == 3


@pytest.mark.slow
def test_whole_chunks_shared_with_the_last_prompt_are_reused_and_replies_do_not_change(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The mechanism at an eighth of the real chunk size (512): a 215-token prompt whose first
    # 207 tokens are shared with the last one keeps three whole 64-token chunks, where 512-token
    # chunks need prompts of 1,400 tokens that take half a minute to evaluate three times.
    chunk = 64
    monkeypatch.setattr(embedded, "_EVAL_CHUNK", chunk)
    shared = "\n".join(f"('AtPosition', 'can{i}', 'on', 'counter{i % 7}')" for i in range(12))
    first = LLMRequest(system="Answer briefly.", user=shared + "\nName a fruit.", max_tokens=8)
    second = LLMRequest(
        system="Answer briefly.", user=shared + "\nName a colour.", n=2, max_tokens=12, seed=7
    )
    warm = EmbeddedBackend(n_ctx=512)
    warm.complete(first)
    assert warm.prompt_tokens_reused == 0
    reused = warm.complete(second)
    kept = warm.prompt_tokens_reused
    assert kept >= 2 * chunk and kept % chunk == 0
    fresh = EmbeddedBackend(n_ctx=512).complete(second)
    assert reused.texts == fresh.texts
    # a prompt sharing less than one whole chunk is evaluated from the start
    warm.complete(LLMRequest(system="Other.", user="Name a tree.", max_tokens=4))
    assert warm.prompt_tokens_reused == kept
