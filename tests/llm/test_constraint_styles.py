"""A served model whose server refuses one constraint style (issue 42, finding 4).

llama.cpp's OpenAI-compatible server answers HTTP 500 to a ``json_schema`` response format;
stalm exited 2 after its retries and never said that ``STALM_LLM_CONSTRAINT_STYLE=gbnf``
exists. Now a run tries the other style once and keeps it with a one-line notice, a server
that takes neither is one error saying what to do, and ``stalm llm check --constrained`` asks
in each style and says which to set. Against :class:`JsonSchemaRefusingServerDouble`, a real
HTTP server on 127.0.0.1 that behaves as llama.cpp's does.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator

import pytest

from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError, StalmWarning
from stalm.llm.backends import LLMRequest, OpenAICompatibleBackend, RetryPolicy
from stalm.llm.constraints import build_constraint
from tests.cli_runner import run_cli
from tests.planners.llm_reply_doubles import plan_reply
from tests.planners.test_stalm import P2_PLAN

from .llm_doubles import (
    JsonSchemaRefusingServerDouble,
    ScriptedHTTPServerDouble,
    ScriptedReply,
    chat_completion,
)

pytestmark = pytest.mark.usefixtures("clean_llm_env")

VOCABULARY = Vocabulary(
    movables=("coke",), regions=("counter1", "counter2"), doors=("kitchen_door",)
)
REPLY = "## Plan for unachieved goals ##\nplan = [('pick', 'coke')]"
CONSTRAINED = LLMRequest(system="s", user="u", constraint=build_constraint(VOCABULARY))


@pytest.fixture
def llama_like() -> Iterator[JsonSchemaRefusingServerDouble]:
    server = JsonSchemaRefusingServerDouble(REPLY)
    server.start()
    yield server
    server.stop()


def _backend(server: ScriptedHTTPServerDouble, **kwargs: object) -> OpenAICompatibleBackend:
    return OpenAICompatibleBackend(
        model="test-model",
        base_url=server.base_url,
        sleep=lambda _s: None,
        retry=RetryPolicy(max_attempts=3, base_delay_s=0.01, max_delay_s=0.01),
        timeout_s=5.0,
        **kwargs,  # type: ignore[arg-type]
    )


def test_a_refused_json_schema_falls_back_to_gbnf_with_a_one_line_notice(llama_like) -> None:
    backend = _backend(llama_like)
    assert backend.constraint_style == "json_schema"
    with pytest.warns(StalmWarning) as heard:
        response = backend.complete(CONSTRAINED)
    assert response.texts == (REPLY,)
    assert len(heard) == 1
    notice = str(heard[0].message)
    assert "\n" not in notice
    assert "refused the output constraint as json_schema: HTTP 500" in notice
    assert "STALM_LLM_CONSTRAINT_STYLE=gbnf" in notice
    # the refusal is not retried as a server failure: one json_schema request, then gbnf
    assert ["response_format" in body for body in llama_like.requests] == [True, False]
    assert llama_like.requests[1]["grammar"] == CONSTRAINED.constraint.gbnf  # type: ignore[union-attr]
    assert backend.constraint_style == "gbnf"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # said once: the next request goes straight to gbnf
        assert backend.complete(CONSTRAINED).texts == (REPLY,)
    assert "response_format" not in llama_like.requests[-1]


def test_the_style_a_server_takes_is_kept_and_its_500s_are_retried_again(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    scripted_server.script = [
        ScriptedReply(body=chat_completion([REPLY])),
        ScriptedReply(status=500, body={"error": {"message": "busy"}}),
        ScriptedReply(body=chat_completion([REPLY])),
    ]
    backend = _backend(scripted_server)
    backend.complete(CONSTRAINED)
    assert backend.complete(CONSTRAINED).texts == (REPLY,)  # retried, same style
    assert all("response_format" in body for body in scripted_server.requests)
    assert backend.constraint_style == "json_schema"


def test_a_server_that_takes_neither_style_is_one_error_saying_what_to_do(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    refusal = {"error": {"message": "unsupported: response_format json_schema, grammar"}}
    scripted_server.script = [ScriptedReply(status=500, body=refusal)]
    with pytest.raises(StalmError) as raised:
        _backend(scripted_server).complete(CONSTRAINED)
    message = str(raised.value)
    assert "\n" not in message
    assert "refused the output constraint in both styles" in message
    assert "json_schema: HTTP 500" in message and "gbnf: HTTP 500" in message
    assert "--unconstrained" in message
    assert len(scripted_server.requests) == 2


def test_llm_check_constrained_finds_the_style_the_server_takes(
    llama_like, monkeypatch, capsys
) -> None:
    url = f"{llama_like.base_url}#test-model"
    assert run_cli(monkeypatch, "llm", "check", "--llm", url, "--constrained") == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "refused json_schema: HTTP 500" in printed
    assert "accepted gbnf" in printed
    assert "set STALM_LLM_CONSTRAINT_STYLE=gbnf" in printed


def test_llm_check_constrained_says_when_the_configured_style_is_taken(
    llama_like, monkeypatch, capsys
) -> None:
    monkeypatch.setenv("STALM_LLM_CONSTRAINT_STYLE", "gbnf")
    url = f"{llama_like.base_url}#test-model"
    assert run_cli(monkeypatch, "llm", "check", "--llm", url, "--constrained") == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "accepted gbnf" in printed
    assert "this server takes the configured style, gbnf" in printed


def test_a_constrained_solve_against_such_a_server_switches_and_solves(monkeypatch, capsys) -> None:
    server = JsonSchemaRefusingServerDouble(plan_reply(P2_PLAN))
    server.start()
    try:
        url = f"{server.base_url}#test-model"
        code = run_cli(monkeypatch, "solve", "P2", "--llm", url, "--constrained", "--cache", "off")
    finally:
        server.stop()
    err = " ".join(capsys.readouterr().err.split())
    assert code == 0, err
    assert "warning:" in err and "STALM_LLM_CONSTRAINT_STYLE=gbnf" in err


def test_a_500_that_names_no_constraint_is_a_server_failure_not_a_refusal(
    scripted_server: ScriptedHTTPServerDouble,
) -> None:
    # a transient or unrelated 500 on the first constrained request keeps the retry policy
    # and the configured style; it is not read as the server refusing json_schema
    scripted_server.script = [ScriptedReply(status=500, body={"error": {"message": "busy"}})]
    with pytest.raises(StalmError) as raised:
        _backend(scripted_server).complete(CONSTRAINED)
    assert "refused the output constraint" not in str(raised.value)
    assert "HTTP 500" in str(raised.value)
    assert all("grammar" not in request for request in scripted_server.requests)
