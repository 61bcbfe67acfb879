"""The reply cache keys a reply by whose it is -- the provider and the server's base URL --
as well as by the model name (issue 30, item 3): a server calling its model
``gpt-4-turbo-2024-04-09`` does not answer for OpenAI's. Entries an older stalm wrote, without
a server, are served only to a backend the user named, with a one-line notice."""

from __future__ import annotations

import pytest

from stalm.errors import StalmError
from stalm.llm.backends import LLMRequest, make_backend
from stalm.llm.backends.identity import spec_identity
from stalm.llm.cache import CachedBackend
from stalm.llm.cache_file import CachedSample, LLMReply, ReplyCache, legacy_sample_key

from .llm_doubles import ScriptedHTTPServerDouble, ScriptedReply, chat_completion

pytestmark = pytest.mark.usefixtures("clean_llm_env")

MODEL = "gpt-4-turbo-2024-04-09"
REQUEST = LLMRequest(system="sys", user="find a plan", n=2, max_tokens=64, seed=3)


def test_a_look_alike_servers_replies_are_not_openais(
    tmp_path, scripted_server: ScriptedHTTPServerDouble, monkeypatch
) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["impostor", "impostor"]))]
    cache = ReplyCache(tmp_path / "replies.sqlite")
    impostor = make_backend(f"{scripted_server.base_url}#{MODEL}")
    made = CachedBackend(impostor, cache).complete(REQUEST)
    assert made.texts == ("impostor", "impostor") and len(cache) == 2
    monkeypatch.setenv("OPENAI_API_KEY", "sk-test")
    openai = CachedBackend(make_backend(f"openai:{MODEL}"), cache, mode="replay")
    with pytest.raises(StalmError) as caught:
        openai.complete(REQUEST)
    assert "https://api.openai.com/v1" in str(caught.value), "the replay says whose it wanted"
    # the same server under another name is the same server
    port = scripted_server.base_url.rsplit(":", 1)[1].split("/")[0]
    again = make_backend(f"http://127.0.0.1:{port}/v1/#{MODEL}")
    assert CachedBackend(again, cache, mode="replay").complete(REQUEST).texts == made.texts


@pytest.mark.parametrize(
    "spec",
    [
        "http://127.0.0.1:8000/v1#m",
        "vllm:m",
        "http://LocalHost:8080/v1/#m",
        "llamacpp:m",
        "embedded",
        "embedded:gemma3-270m",
    ],
)
def test_a_specs_identity_is_its_backends_without_building_it(spec: str) -> None:
    backend = make_backend(spec)
    assert spec_identity(spec).key == backend.identity  # type: ignore[attr-defined]
    assert spec_identity(spec).model == backend.model


def test_the_identity_of_openai_needs_no_key() -> None:
    identity = spec_identity(f"openai:{MODEL}")
    assert identity.key == "openai-compatible https://api.openai.com/v1"
    assert identity.model == MODEL
    assert "https://api.openai.com/v1" in identity.describe()


def _legacy_entry(cache: ReplyCache, name: str, model: str) -> None:
    """One reply as a stalm before server identities stored it (keyed by name and model)."""
    key = legacy_sample_key(name, model, REQUEST, 0)
    reply = LLMReply("old reply", 10, 5, 1.0, "stop")
    cache.put_many([CachedSample(key, name, model, REQUEST, 0, reply, 1.0)])


def test_old_entries_are_served_with_a_notice_only_when_the_user_named_the_backend(
    tmp_path, scripted_server: ScriptedHTTPServerDouble
) -> None:
    cache = ReplyCache(tmp_path / "replies.sqlite")
    _legacy_entry(cache, "openai-compatible", MODEL)
    single = LLMRequest(system="sys", user="find a plan", n=1, max_tokens=64, seed=3)
    backend = make_backend(f"{scripted_server.base_url}#{MODEL}")
    notes: list[str] = []
    named = CachedBackend(backend, cache, mode="replay", notify=notes.append)
    assert named.complete(single).texts == ("old reply",)
    named.complete(single)
    assert len(notes) == 1 and "\n" not in notes[0], "one notice, one line"
    assert MODEL in notes[0] and scripted_server.base_url in notes[0]
    from_record = CachedBackend(backend, cache, mode="replay", legacy=False)
    with pytest.raises(StalmError, match="lacks 1 of 1"):
        from_record.complete(single)
    assert scripted_server.paths == [], "replay asks no server"


def test_a_solve_replay_says_whose_replies_it_replays(
    monkeypatch, capsys, scripted_server: ScriptedHTTPServerDouble
) -> None:
    from tests.cli_runner import run_cli

    spec = f"{scripted_server.base_url}#{MODEL}"
    args = ["solve", "P2", "--proposer", "llm", "--llm", spec, "--cache", "replay"]
    short = ["--sims", "2", "--set", "budget.horizon=1", "--set", "execution.rule=best_q"]
    ReplyCache()  # an empty cache in the default place: replay opens it read-only and misses
    assert run_cli(monkeypatch, *args, *short) == 2, "an empty cache: the replay misses"
    err = capsys.readouterr().err
    assert f"replaying the replies of model {MODEL!r} on {scripted_server.base_url}" in err
    assert f"of openai-compatible {scripted_server.base_url}" in err, "the miss says whose"
    assert scripted_server.paths == []
