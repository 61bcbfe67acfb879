"""Test doubles for the language-model tests: a scripted HTTP server standing in for an
OpenAI-compatible one, canned chat-completion bodies, and a free loopback port."""

from __future__ import annotations

import json
import socket
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on (bound, then released)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@dataclass
class ScriptedReply:
    """One canned HTTP answer of the scripted test server."""

    status: int = 200
    body: Any = None  # dict/list -> JSON; str -> sent as is
    delay_s: float = 0.0
    headers: dict[str, str] = field(default_factory=dict)
    content_type: str | None = None
    """None: JSON for dict/list bodies, text/plain for strings."""
    chunk_delay_s: float = 0.0
    """Above 0, the body is sent one byte at a time with this pause (a slow stream)."""


def chat_completion(
    contents: list[str], prompt_tokens: int = 10, completion_tokens: int = 6
) -> dict[str, Any]:
    """A minimal OpenAI chat-completion body with one choice per content."""
    return {
        "id": "chatcmpl-test",
        "object": "chat.completion",
        "created": 0,
        "model": "test-model",
        "choices": [
            {
                "index": i,
                "message": {"role": "assistant", "content": text},
                "finish_reason": "stop",
            }
            for i, text in enumerate(contents)
        ],
        "usage": {
            "prompt_tokens": prompt_tokens,
            "completion_tokens": completion_tokens,
            "total_tokens": prompt_tokens + completion_tokens,
        },
    }


class ScriptedHTTPServerDouble:
    """A test double of an OpenAI-compatible server on a real loopback socket.

    POST answers come from ``script`` in order (the last one repeats) unless ``responder``
    is set, which builds the answer from the request body. Every request body is recorded.
    """

    def __init__(self) -> None:
        self.script: list[ScriptedReply] = []
        self.responder: Any = None
        self.requests: list[dict[str, Any]] = []
        self.paths: list[str] = []
        self.authorizations: list[str] = []
        """The Authorization header of each POST ('' when absent)."""
        self._lock = threading.Lock()
        double = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, format: str, *args: Any) -> None:  # quiet
                pass

            def _answer(self, reply: ScriptedReply) -> None:
                if reply.delay_s:
                    time.sleep(reply.delay_s)
                payload = (
                    reply.body if isinstance(reply.body, str) else json.dumps(reply.body)
                ).encode()
                try:
                    self.send_response(reply.status)
                    content_type = reply.content_type or (
                        "text/plain" if isinstance(reply.body, str) else ("application/json")
                    )
                    self.send_header("Content-Type", content_type)
                    self.send_header("Content-Length", str(len(payload)))
                    for name, value in reply.headers.items():
                        self.send_header(name, value)
                    self.end_headers()
                    if reply.chunk_delay_s > 0:
                        for index in range(len(payload)):
                            self.wfile.write(payload[index : index + 1])
                            self.wfile.flush()
                            time.sleep(reply.chunk_delay_s)
                    else:
                        self.wfile.write(payload)
                except OSError:  # broken pipe or reset
                    pass  # the client gave up (timeout tests)

            def do_GET(self) -> None:
                double.paths.append(self.path)
                self._answer(
                    ScriptedReply(
                        body={
                            "object": "list",
                            "data": [
                                {
                                    "id": "listed-model",
                                    "object": "model",
                                    "created": 0,
                                    "owned_by": "t",
                                }
                            ],
                        }
                    )
                )

            def do_POST(self) -> None:
                length = int(self.headers.get("Content-Length", "0"))
                body = json.loads(self.rfile.read(length) or b"{}")
                with double._lock:
                    double.requests.append(body)
                    double.paths.append(self.path)
                    double.authorizations.append(self.headers.get("Authorization", ""))
                    if double.responder is not None:
                        reply = double.responder(body)
                    else:
                        reply = (
                            double.script.pop(0) if len(double.script) > 1 else (double.script[0])
                        )
                self._answer(reply)

        self._server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self._server.daemon_threads = True
        self._thread = threading.Thread(
            target=self._server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
        )

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self._server.server_address[1]}/v1"

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._server.shutdown()
        self._server.server_close()


class CountingFakeBackend:
    """A fake backend whose replies spell out what was asked; it counts its calls.

    Sample ``i`` of a request is ``"<user>|seed=<seed + i>|t=<temperature>"``, so tests can
    see exactly which draws the cache served and which it asked for.
    """

    def __init__(self, name: str = "fake", model: str = "fake-model") -> None:
        self._name = name
        self._model = model
        self.requests: list[Any] = []

    @property
    def name(self) -> str:
        return self._name

    @property
    def model(self) -> str:
        return self._model

    @property
    def description(self) -> str:
        return "a fake backend for tests"

    def complete(self, request: Any) -> Any:
        from stalm.llm.backends.base import LLMReply, LLMResponse

        self.requests.append(request)
        replies = tuple(
            LLMReply(
                text=f"{request.user}|seed={request.sample_seed(i)}|t={request.temperature}",
                prompt_tokens=10 if i == 0 else 0,
                completion_tokens=5,
                latency_s=0.01,
                finish_reason="stop",
            )
            for i in range(request.n)
        )
        return LLMResponse(replies=replies, backend=self._name, model=self._model)


class FailingFakeBackend(CountingFakeBackend):
    """A fake backend that must not be called (replay tests)."""

    def complete(self, request: Any) -> Any:
        raise AssertionError(f"the model was asked although the cache should answer: {request}")


LLAMA_CPP_SCHEMA_ERROR = {
    "error": {
        "code": 500,
        "message": "JSON schema conversion failed:\nUnrecognized schema: prefixItems",
        "type": "server_error",
    }
}
"""What llama.cpp's server answers (HTTP 500) to a JSON schema it cannot convert."""


class JsonSchemaRefusingServerDouble(ScriptedHTTPServerDouble):
    """A test double of llama.cpp's OpenAI-compatible server on a real loopback socket: HTTP
    500 (:data:`LLAMA_CPP_SCHEMA_ERROR`) to any request with a ``json_schema`` response
    format; ``text`` as the one reply to any other (a GBNF grammar is taken, not enforced).
    Every request body is recorded, as the scripted double does."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text
        self.responder = self._reply

    def _reply(self, body: dict[str, Any]) -> ScriptedReply:
        response_format = body.get("response_format") or {}
        if response_format.get("type") == "json_schema":
            return ScriptedReply(status=500, body=LLAMA_CPP_SCHEMA_ERROR)
        return ScriptedReply(body=chat_completion([self.text]))
