"""The OpenAI-compatible backend against a real llama.cpp server (llama-cpp-python's) serving
the embedded model on a loopback port: plain and GBNF-constrained batches."""

from __future__ import annotations

import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator

import pytest

from stalm.domain.vocabulary import Vocabulary
from stalm.llm.backends import LLMRequest, OpenAICompatibleBackend
from stalm.llm.backends.embedded_models import locate_embedded_model
from stalm.llm.constraints import ConstraintLimits, build_constraint
from stalm.llm.reply_parser import parse_reply

from .llm_doubles import free_port

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("clean_llm_env")]

VOCABULARY = Vocabulary(
    movables=("coke", "sprite"), regions=("counter1", "counter2"), doors=("kitchen_door",)
)
STARTUP_TIMEOUT_S = 90.0


@pytest.fixture(scope="module")
def llama_server_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    pytest.importorskip("llama_cpp.server.app", reason="needs llama-cpp-python[server]")
    port = free_port()
    command = [
        sys.executable,
        "-m",
        "llama_cpp.server",
        "--model",
        str(locate_embedded_model("smollm2")),
        "--host",
        "127.0.0.1",
        "--port",
        str(port),
        "--n_ctx",
        "1024",
    ]
    # The server logs a lot; a file (not a pipe nobody drains) keeps it from blocking.
    log_path = tmp_path_factory.mktemp("llama-server") / "server.log"
    log = log_path.open("wb")
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}/v1"
    try:
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        while True:
            if process.poll() is not None:
                errors = log_path.read_text(errors="replace")
                pytest.fail(f"llama_cpp.server exited with {process.returncode}: {errors[-2000:]}")
            try:
                with urllib.request.urlopen(f"{url}/models", timeout=2) as answer:
                    if answer.status == 200:
                        break
            except (urllib.error.URLError, ConnectionError, TimeoutError):
                pass
            if time.monotonic() > deadline:
                pytest.fail(f"llama_cpp.server did not answer within {STARTUP_TIMEOUT_S} s")
            time.sleep(0.2)
        yield url
    finally:
        process.terminate()
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=15)
        log.close()


def test_plain_batch_is_filled_although_the_server_ignores_n(llama_server_url: str) -> None:
    backend = OpenAICompatibleBackend(base_url=llama_server_url, constraint_style="gbnf")
    assert backend.model.endswith(".gguf")  # llama-cpp-python lists the model by its path
    request = LLMRequest(system="Answer briefly.", user="Name a fruit.", n=3, max_tokens=12, seed=3)
    response = backend.complete(request)
    assert len(response.replies) == 3
    assert all(reply.completion_tokens > 0 for reply in response.replies)
    assert response.prompt_tokens > 0


def test_gbnf_constrained_reply_follows_the_template(llama_server_url: str) -> None:
    backend = OpenAICompatibleBackend(base_url=llama_server_url, constraint_style="gbnf")
    constraint = build_constraint(
        VOCABULARY, ConstraintLimits(max_challenge_lines=2, max_line_chars=60, max_steps=4)
    )
    request = LLMRequest(
        system="Reply with challenges, then a plan.",
        user="Goal: coke on counter2. coke is behind kitchen_door.",
        n=2,
        max_tokens=200,
        seed=5,
        constraint=constraint,
    )
    response = backend.complete(request)
    assert len(response.replies) == 2
    for reply in response.replies:
        parsed = parse_reply(reply.text, VOCABULARY)
        assert parsed.reason is None and parsed.plan, reply.text
