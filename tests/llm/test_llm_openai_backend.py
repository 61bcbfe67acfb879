"""The OpenAI-compatible backend against real loopback sockets: a scripted server double for
errors, retries, batching and constraint fields, and a closed port for connection refused."""

from __future__ import annotations

import json
import time

import pytest

from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.backends import LLMRequest, OpenAICompatibleBackend, RetryPolicy
from stalm.llm.constraints import PLAN_HEADER, build_constraint

from .llm_doubles import ScriptedHTTPServerDouble, ScriptedReply, chat_completion, free_port

pytestmark = pytest.mark.usefixtures("clean_llm_env")


class RecordingSleepDouble:
    """Stands in for time.sleep: records backoff delays instead of waiting."""

    def __init__(self) -> None:
        self.delays: list[float] = []

    def __call__(self, seconds: float) -> None:
        self.delays.append(seconds)


def make(
    server: ScriptedHTTPServerDouble, sleep: RecordingSleepDouble | None = None, **kwargs: object
) -> OpenAICompatibleBackend:
    options: dict[str, object] = {
        "model": "test-model",
        "base_url": server.base_url,
        "sleep": sleep or RecordingSleepDouble(),
        "timeout_s": 5.0,
    }
    options.update(kwargs)
    return OpenAICompatibleBackend(**options)  # type: ignore[arg-type]


REQUEST = LLMRequest(system="sys", user="hello", n=1, temperature=0.5, max_tokens=32, seed=7)


def test_single_reply_and_request_fields(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["hi there"], 12, 3))]
    response = make(scripted_server).complete(REQUEST)
    assert response.texts == ("hi there",)
    assert (response.backend, response.model, response.from_cache) == (
        "openai-compatible",
        "test-model",
        False,
    )
    reply = response.replies[0]
    assert (reply.prompt_tokens, reply.completion_tokens, reply.finish_reason) == (12, 3, "stop")
    sent = scripted_server.requests[0]
    assert scripted_server.paths == ["/v1/chat/completions"]
    assert sent["model"] == "test-model"
    assert sent["messages"] == [
        {"role": "system", "content": "sys"},
        {"role": "user", "content": "hello"},
    ]
    assert (sent["temperature"], sent["max_tokens"], sent["seed"]) == (0.5, 32, 7)
    assert "n" not in sent and "response_format" not in sent and "grammar" not in sent


def test_server_honouring_n_gets_one_call(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["a", "bb", "ccc"], 20, 12))]
    request = LLMRequest(system="s", user="u", n=3, seed=100)
    response = make(scripted_server).complete(request)
    assert response.texts == ("a", "bb", "ccc")
    assert len(scripted_server.requests) == 1
    assert scripted_server.requests[0]["n"] == 3
    # Usage is per call: prompt counted once, completion tokens shared out, sums preserved.
    assert response.prompt_tokens == 20 and response.completion_tokens == 12
    assert [r.prompt_tokens for r in response.replies] == [20, 0, 0]


def test_server_ignoring_n_is_filled_concurrently_with_offset_seeds(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    scripted_server.responder = lambda body: ScriptedReply(
        body=chat_completion([f"seed={body.get('seed')}"])
    )
    backend = make(scripted_server)
    response = backend.complete(LLMRequest(system="s", user="u", n=4, seed=10))
    assert response.texts == ("seed=10", "seed=11", "seed=12", "seed=13")
    assert len(scripted_server.requests) == 4
    # Learned: the next batch goes straight to one call per sample.
    scripted_server.requests.clear()
    response = backend.complete(LLMRequest(system="s", user="u", n=2, seed=50))
    assert response.texts == ("seed=50", "seed=51")
    assert sorted(r["seed"] for r in scripted_server.requests) == [50, 51]
    assert all("n" not in r for r in scripted_server.requests)


def test_json_schema_constraint_is_sent_and_reply_converted(
    scripted_server: ScriptedHTTPServerDouble, p5_vocabulary: Vocabulary
) -> None:
    structured = {"challenges": "1. door", "plan": [["open", "kitchen_door"], ["pick", "coke"]]}
    scripted_server.script = [ScriptedReply(body=chat_completion([json.dumps(structured)]))]
    constraint = build_constraint(p5_vocabulary)
    request = LLMRequest(system="s", user="u", constraint=constraint)
    response = make(scripted_server, constraint_style="json_schema").complete(request)
    sent = scripted_server.requests[0]
    assert sent["response_format"]["type"] == "json_schema"
    assert sent["response_format"]["json_schema"]["schema"] == constraint.json_schema()
    assert sent["response_format"]["json_schema"]["strict"] is False
    assert "grammar" not in sent
    assert PLAN_HEADER in response.texts[0]
    assert "plan = [('open', 'kitchen_door'), ('pick', 'coke')]" in response.texts[0]


def test_malformed_json_reply_is_kept_raw_for_the_parser_to_reject(
    scripted_server: ScriptedHTTPServerDouble, p5_vocabulary: Vocabulary
) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(['{"challenges": "cut'], 5, 5))]
    request = LLMRequest(system="s", user="u", constraint=build_constraint(p5_vocabulary))
    response = make(scripted_server).complete(request)
    assert response.texts == ('{"challenges": "cut',)


def test_gbnf_constraint_is_sent_as_grammar_field(
    scripted_server: ScriptedHTTPServerDouble, p5_vocabulary: Vocabulary
) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["plan = []"]))]
    constraint = build_constraint(p5_vocabulary)
    request = LLMRequest(system="s", user="u", constraint=constraint)
    make(scripted_server, constraint_style="gbnf").complete(request)
    sent = scripted_server.requests[0]
    assert sent["grammar"] == constraint.gbnf
    assert "response_format" not in sent


def test_500_then_200_is_retried_with_backoff(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [
        ScriptedReply(status=500, body={"error": {"message": "boom"}}),
        ScriptedReply(status=503, body={"error": {"message": "busy"}}),
        ScriptedReply(body=chat_completion(["ok"])),
    ]
    sleep = RecordingSleepDouble()
    retry = RetryPolicy(max_attempts=4, base_delay_s=0.5, max_delay_s=10)
    response = make(scripted_server, sleep, retry=retry).complete(REQUEST)
    assert response.texts == ("ok",)
    assert len(scripted_server.requests) == 3
    assert sleep.delays == [0.5, 1.0]


def test_rate_limit_honours_retry_after_and_gives_up_bounded(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    scripted_server.script = [
        ScriptedReply(
            status=429, body={"error": {"message": "slow down"}}, headers={"Retry-After": "3"}
        )
    ]
    sleep = RecordingSleepDouble()
    retry = RetryPolicy(max_attempts=3, base_delay_s=1.0, max_delay_s=5.0)
    with pytest.raises(StalmError) as error:
        make(scripted_server, sleep, retry=retry).complete(REQUEST)
    assert len(scripted_server.requests) == 3
    assert sleep.delays == [3.0, 3.0]
    message = str(error.value)
    assert scripted_server.base_url in message and "test-model" in message
    assert "429" in message


@pytest.mark.parametrize(
    ("status", "expected"), [(401, "API key"), (403, "API key"), (404, "no such model")]
)
def test_client_errors_fail_at_once_naming_url_and_model(
    scripted_server: ScriptedHTTPServerDouble, status: int, expected: str
) -> None:
    scripted_server.script = [ScriptedReply(status=status, body={"error": {"message": "no"}})]
    sleep = RecordingSleepDouble()
    with pytest.raises(StalmError) as error:
        make(scripted_server, sleep).complete(REQUEST)
    message = str(error.value)
    assert expected in message
    assert scripted_server.base_url in message and "test-model" in message
    assert len(scripted_server.requests) == 1 and sleep.delays == []


def test_garbage_body_is_one_clear_error(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [ScriptedReply(body="<html>this is not json</html>")]
    with pytest.raises(StalmError) as error:
        make(scripted_server).complete(REQUEST)
    message = str(error.value)
    assert "not a chat completion" in message and scripted_server.base_url in message


def test_json_without_choices_is_one_clear_error(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    scripted_server.script = [ScriptedReply(body={"hello": "world"})]
    with pytest.raises(StalmError, match="chat completion"):
        make(scripted_server).complete(REQUEST)


def test_timeout_is_retried_then_reported(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["late"]), delay_s=1.5)]
    sleep = RecordingSleepDouble()
    backend = make(scripted_server, sleep, timeout_s=0.3, retry=RetryPolicy(max_attempts=2))
    started = time.perf_counter()
    with pytest.raises(StalmError) as error:
        backend.complete(REQUEST)
    assert time.perf_counter() - started < 3.0
    message = str(error.value)
    assert "no answer within 0.3 s" in message
    assert scripted_server.base_url in message and "test-model" in message
    assert len(sleep.delays) == 1


def test_connection_refused_names_url_and_model() -> None:
    url = f"http://127.0.0.1:{free_port()}/v1"
    backend = OpenAICompatibleBackend(model="some-model", base_url=url, timeout_s=2.0)
    with pytest.raises(StalmError) as error:
        backend.complete(REQUEST)
    message = str(error.value)
    assert url in message and "some-model" in message and "cannot reach" in message


def test_model_is_discovered_from_a_local_server(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    backend = OpenAICompatibleBackend(base_url=scripted_server.base_url)
    assert backend.model == "listed-model"
    assert scripted_server.paths == ["/v1/models"]


def test_environment_supplies_url_model_and_key(
    scripted_server: ScriptedHTTPServerDouble, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("STALM_LLM_BASE_URL", scripted_server.base_url)
    monkeypatch.setenv("STALM_LLM_MODEL", "env-model")
    monkeypatch.setenv("STALM_LLM_CONSTRAINT_STYLE", "gbnf")
    backend = OpenAICompatibleBackend()
    assert (backend.url, backend.model, backend.constraint_style) == (
        scripted_server.base_url,
        "env-model",
        "gbnf",
    )


def test_openai_itself_needs_key_and_model(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(StalmError, match="API key"):
        OpenAICompatibleBackend(model="gpt-4-turbo")
    monkeypatch.setenv("OPENAI_API_KEY", "sk-test")
    with pytest.raises(StalmError, match="no model"):
        OpenAICompatibleBackend()
    assert OpenAICompatibleBackend(model="gpt-4-turbo").url == "https://api.openai.com/v1"


def test_unknown_constraint_style_is_a_user_error() -> None:
    with pytest.raises(StalmError, match="constraint style"):
        OpenAICompatibleBackend(model="m", base_url="http://127.0.0.1:1/v1", constraint_style="x")


# --- Issue 16: the request's deadline bounds every call, retries and all -----------------------


def _deadline_request(seconds: float) -> LLMRequest:
    return LLMRequest(
        system="sys", user="hello", n=1, max_tokens=32, seed=7, deadline=time.monotonic() + seconds
    )


def test_a_hanging_server_is_cut_at_the_deadline(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["late"]), delay_s=30)]
    backend = make(scripted_server, timeout_s=20.0)
    started = time.monotonic()
    response = backend.complete(_deadline_request(1.0))
    assert time.monotonic() - started < 2.5
    assert response.replies == ()  # nothing answered before the deadline


def test_a_slow_stream_is_cut_at_the_deadline(scripted_server: ScriptedHTTPServerDouble) -> None:
    # headers at once, then the body one byte every 0.1 s: each read is quick, the whole is not
    scripted_server.script = [ScriptedReply(body=chat_completion(["x" * 200]), chunk_delay_s=0.1)]
    backend = make(scripted_server, timeout_s=20.0)
    started = time.monotonic()
    response = backend.complete(_deadline_request(1.0))
    assert time.monotonic() - started < 2.5
    assert response.replies == ()


def test_retries_stop_at_the_deadline(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [ScriptedReply(status=500, body={"error": {"message": "boom"}})]
    backend = make(
        scripted_server,
        sleep=time.sleep,
        retry=RetryPolicy(max_attempts=10, base_delay_s=0.4, max_delay_s=0.4),
    )
    started = time.monotonic()
    response = backend.complete(_deadline_request(1.0))
    assert time.monotonic() - started < 2.0
    assert response.replies == ()
    assert 1 <= len(scripted_server.requests) <= 4


def test_a_backoff_longer_than_the_time_left_is_not_slept(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    scripted_server.script = [ScriptedReply(status=503, body={"error": {"message": "busy"}})]
    sleep = RecordingSleepDouble()
    retry = RetryPolicy(max_attempts=4, base_delay_s=30.0, max_delay_s=60.0)
    response = make(scripted_server, sleep, retry=retry).complete(_deadline_request(2.0))
    assert response.replies == () and sleep.delays == []
    assert len(scripted_server.requests) == 1


def test_a_passed_deadline_sends_nothing(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["hi"]))]
    response = make(scripted_server).complete(_deadline_request(-1.0))
    assert response.replies == () and scripted_server.requests == []


def test_an_answer_before_the_deadline_is_kept(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["in time"]), delay_s=0.2)]
    response = make(scripted_server).complete(_deadline_request(5.0))
    assert response.texts == ("in time",)


# --- Issue 16: malformed answers and URLs are one clear error; keys go where they belong -------


def test_malformed_json_body_is_one_clear_error(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [
        ScriptedReply(body='{"choices": [{"message": ', content_type="application/json")
    ]
    with pytest.raises(StalmError) as error:
        make(scripted_server).complete(REQUEST)
    message = str(error.value)
    assert "JSON" in message and scripted_server.base_url in message


@pytest.mark.parametrize("url", ["http://[::1/v1", "http://:80/v1", "ftp://host/v1", "http://"])
def test_a_malformed_base_url_is_one_clear_error(url: str) -> None:
    with pytest.raises(StalmError, match="base URL"):
        OpenAICompatibleBackend(model="m", base_url=url)


def test_openai_key_is_not_sent_to_a_custom_server(
    scripted_server: ScriptedHTTPServerDouble, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("OPENAI_API_KEY", "sk-secret-openai-key")
    scripted_server.script = [ScriptedReply(body=chat_completion(["hi"]))]
    OpenAICompatibleBackend(model="m", base_url=scripted_server.base_url).complete(REQUEST)
    assert "sk-secret-openai-key" not in scripted_server.authorizations[0]
    monkeypatch.setenv("STALM_LLM_API_KEY", "sk-for-my-server")
    OpenAICompatibleBackend(model="m", base_url=scripted_server.base_url).complete(REQUEST)
    assert scripted_server.authorizations[1] == "Bearer sk-for-my-server"


def test_openai_key_still_goes_to_openai(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OPENAI_API_KEY", "sk-openai")
    assert OpenAICompatibleBackend(model="gpt-4-turbo").key_source == "OPENAI_API_KEY"
    backend = OpenAICompatibleBackend(model="gpt-4-turbo", base_url="https://api.openai.com/v1/")
    assert backend.key_source == "OPENAI_API_KEY"
    for lookalike in ("https://api.openai.com.evil.example/v1", "http://api.openai.com/v1"):
        assert OpenAICompatibleBackend(model="m", base_url=lookalike).key_source is None


def test_the_reply_cache_accepts_a_batch_the_deadline_cut_short(
    scripted_server: ScriptedHTTPServerDouble, tmp_path
) -> None:
    from stalm.llm.cache import CachedBackend
    from stalm.llm.cache_file import ReplyCache

    scripted_server.script = [ScriptedReply(status=503, body={"error": {"message": "busy"}})]
    retry = RetryPolicy(max_attempts=4, base_delay_s=30.0, max_delay_s=60.0)
    backend = make(scripted_server, RecordingSleepDouble(), retry=retry)
    cached = CachedBackend(backend, ReplyCache(tmp_path / "replies.sqlite"), mode="use")
    request = LLMRequest(system="s", user="u", n=3, seed=1, deadline=time.monotonic() + 5.0)
    response = cached.complete(request)  # the backoff would outlast the deadline: no replies
    assert response.replies == ()
