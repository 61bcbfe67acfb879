"""OpenAI's chat API and every server that speaks it (vLLM, Ollama, llama.cpp, LM Studio).

The paper queried ``gpt-4-turbo``; people reproducing it will point stalm at OpenAI or at an
open model on their own server. One backend covers all of them because they share the chat
completions API, with three differences handled here:

* **Batches.** OpenAI and vLLM honour ``n`` (several samples of one prompt in one call);
  llama.cpp's server ignores it and returns one. When fewer choices come back than asked,
  the rest are requested concurrently, one per call with seeds ``seed + i``, and the backend
  remembers that this server ignores ``n`` so later batches go straight to concurrent calls.
* **Constrained output.** Servers with structured output take a JSON schema
  (``constraint_style="json_schema"``; the JSON reply is turned back into the paper's text
  form); llama.cpp's servers take a GBNF grammar in the ``grammar`` field
  (``constraint_style="gbnf"``). A server that refuses the one sent first gets the other,
  with a one-line notice (:mod:`stalm.llm.backends.constraint_styles`).
* **Failures.** Rate limits, 5xx and timeouts are retried with bounded exponential backoff;
  a wrong key, an unknown model, an unreachable server or a body that is not JSON is one
  clear :class:`~stalm.errors.StalmError` naming the URL and the model.

A request's ``deadline`` (a trial's time budget) bounds everything one request does: each
attempt waits at most until the deadline (the whole answer, not just each read: a server that
trickles its body slowly is cut too), no backoff sleeps past it, and past it no attempt
starts. What was not answered by then is left out of the response, as the embedded backend
does; the planner sees its time is up and writes its result. The deadline and the retries
live in :mod:`stalm.llm.backends.retries`, reading a completion into replies in
:mod:`stalm.llm.backends.chat_replies`; this module builds the requests and sends them.

``OPENAI_API_KEY`` is only ever sent to the OpenAI API itself (``https://api.openai.com``);
any other server gets ``STALM_LLM_API_KEY`` or no key, so pointing ``--llm`` at some host
cannot leak an OpenAI key to it.
"""

from __future__ import annotations

import functools
import os
import threading
import time
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

from stalm.errors import StalmError, StalmWarning
from stalm.llm.backends.base import LLMReply, LLMRequest, LLMResponse
from stalm.llm.backends.chat_replies import chat_replies
from stalm.llm.backends.constraint_styles import (
    CONSTRAINT_STYLE_ENV,
    CONSTRAINT_STYLES,
    ConstraintRefused,
    ConstraintStyle,
    both_refused,
    check_constraint_style,
    other_style,
    refuses_constraint,
    switched_notice,
)
from stalm.llm.backends.retries import (
    RETRYABLE_STATUS,
    DeadlinePassed,
    RetryPolicy,
    retry_after_s,
    run_until,
    time_left,
)
from stalm.llm.backends.server_urls import check_base_url, env, is_openai_api, server_url

if TYPE_CHECKING:  # imported where used: it adds a third of a second to every CLI start
    import openai

__all__ = [
    "CONSTRAINT_STYLES",
    "ConstraintStyle",
    "OpenAICompatibleBackend",
    "check_constraint_style",
    "server_url",
]

BASE_URL_ENV = "STALM_LLM_BASE_URL"
MODEL_ENV = "STALM_LLM_MODEL"
API_KEY_ENV = "STALM_LLM_API_KEY"
OPENAI_DEFAULT_BASE_URL = "https://api.openai.com/v1"
# Local servers accept any key, but the openai client refuses to start without one.
_PLACEHOLDER_KEY = "sk-no-key-required"
OPENAI_KEY_ENV = "OPENAI_API_KEY"
DISCOVERY_TIMEOUT_S = 15.0
"""Longest wait for a server's model list: it is asked outside any trial's deadline."""


SERVER_PROVIDER = "openai-compatible"
"""The provider part of a server's identity (:mod:`stalm.llm.backends.identity`)."""


class OpenAICompatibleBackend:
    """A chat-completions client for OpenAI or any server speaking the same API.

    Arguments left as None come from the environment: ``base_url`` from
    ``STALM_LLM_BASE_URL`` then ``OPENAI_BASE_URL`` (else OpenAI itself); ``model`` from
    ``STALM_LLM_MODEL`` (else, for a local server, the first model it lists); ``api_key``
    from ``STALM_LLM_API_KEY``, then, for the OpenAI API only, ``OPENAI_API_KEY``;
    ``constraint_style`` from ``STALM_LLM_CONSTRAINT_STYLE`` (else ``"json_schema"``).
    Nothing touches the network until the first request. ``sleep`` is the backoff's clock,
    injectable so tests need not wait.
    """

    def __init__(
        self,
        model: str | None = None,
        base_url: str | None = None,
        api_key: str | None = None,
        *,
        constraint_style: ConstraintStyle | str | None = None,
        json_schema_strict: bool = False,
        timeout_s: float = 120.0,
        retry: RetryPolicy | None = None,
        sleep: Callable[[float], None] = time.sleep,
        max_concurrency: int = 8,
    ) -> None:
        self._base_url = (base_url or env(BASE_URL_ENV, "OPENAI_BASE_URL") or "").rstrip("/")
        if self._base_url:
            check_base_url(self._base_url)
        self._is_openai = not self._base_url or is_openai_api(self._base_url)
        self._model = model or env(MODEL_ENV)
        key, self._key_source = api_key, "argument" if api_key else None
        if not key:
            # an OpenAI key is for OpenAI: another server never sees it (module docstring)
            names = (API_KEY_ENV, OPENAI_KEY_ENV) if self._is_openai else (API_KEY_ENV,)
            self._key_source = next((name for name in names if os.environ.get(name)), None)
            key = os.environ[self._key_source] if self._key_source else None
        if self._is_openai:
            if not key:
                raise StalmError(
                    f"no API key for {self.url}: set {API_KEY_ENV} or {OPENAI_KEY_ENV} "
                    f"(or {BASE_URL_ENV} to use a local server instead)"
                )
            if not self._model:
                raise StalmError(
                    f"no model named for {self.url}: use --llm openai:MODEL or set {MODEL_ENV}"
                )
        self._constraint_style = check_constraint_style(
            constraint_style or env(CONSTRAINT_STYLE_ENV) or "json_schema"
        )
        self._json_schema_strict = json_schema_strict
        self._timeout_s = timeout_s
        self._retry = retry or RetryPolicy()
        self._sleep = sleep
        self._max_concurrency = max(1, max_concurrency)
        self._lock = threading.Lock()
        # Learned from the server: None until a batch shows whether it honours ``n``.
        self._server_honours_n: bool | None = None
        self._style_taken = False
        """A constrained request was answered: the style is the server's (no more trying)."""
        import openai

        self._client = openai.OpenAI(
            api_key=key or _PLACEHOLDER_KEY,
            base_url=self._base_url or None,
            timeout=timeout_s,
            max_retries=0,  # retries are ours: bounded, logged in errors, testable
        )

    @property
    def name(self) -> str:
        return SERVER_PROVIDER

    @property
    def url(self) -> str:
        return self._base_url or OPENAI_DEFAULT_BASE_URL

    @property
    def identity(self) -> str:
        """Whose replies these are: the provider and the server, as the reply cache keys them
        (:mod:`stalm.llm.backends.identity`)."""
        return f"{SERVER_PROVIDER} {server_url(self.url)}"

    @property
    def constraint_style(self) -> ConstraintStyle:
        return self._constraint_style

    @property
    def key_source(self) -> str | None:
        """Where the API key sent comes from (an environment variable's name, or
        ``"argument"``); None when no key is sent."""
        return self._key_source

    @property
    def model(self) -> str:
        """The model name; for a local server given none, the first one it lists (one call)."""
        with self._lock:
            if self._model is None:
                self._model = self._discover_model()
            return self._model

    @property
    def description(self) -> str:
        where = "the OpenAI API" if self._is_openai else f"the server at {self.url}"
        return (
            f"Model {self.model!r} on {where} (OpenAI-compatible chat API; constrained output "
            f"via {self._constraint_style})."
        )

    def _describe(self, model: str | None = None) -> str:
        return f"server {self.url} (model {model or self._model or '?'!r})"

    def _discover_model(self) -> str:
        import openai

        wait_s = min(self._timeout_s, DISCOVERY_TIMEOUT_S)
        try:
            listing = run_until(
                lambda: self._client.models.list(timeout=wait_s), time.monotonic() + wait_s
            )
            names = [entry.id for entry in listing.data]
        except (DeadlinePassed, openai.APITimeoutError):
            raise StalmError(
                f"{self.url} did not list its models within {wait_s:g} s; name the model with "
                f"{MODEL_ENV} or --llm URL#MODEL"
            ) from None
        except openai.APIConnectionError as error:
            raise StalmError(
                f"cannot reach {self.url} to list its models ({error}); is the server running? "
                f"Or name the model with {MODEL_ENV}"
            ) from error
        except (openai.OpenAIError, AttributeError, TypeError, ValueError) as error:
            raise StalmError(
                f"cannot list the models of {self.url} ({error}); name the model with "
                f"{MODEL_ENV} or --llm URL#MODEL"
            ) from error
        if not names:
            raise StalmError(f"server {self.url} lists no models; name one with {MODEL_ENV}")
        return str(names[0])

    def complete(self, request: LLMRequest) -> LLMResponse:
        model = self.model
        replies: list[LLMReply] = []
        try:
            if request.n == 1 or self._server_honours_n is not False:
                replies = self._call(request, model, n=request.n, seed=request.seed)[: request.n]
                if request.n > 1:
                    with self._lock:
                        self._server_honours_n = len(replies) == request.n
            missing = range(len(replies), request.n)
            if missing:
                workers = min(len(missing), self._max_concurrency)
                with ThreadPoolExecutor(max_workers=workers) as pool:
                    futures = [
                        pool.submit(self._call, request, model, 1, request.sample_seed(i))
                        for i in missing
                    ]
                    for future in futures:
                        replies.extend(future.result()[:1])
        except DeadlinePassed:
            # what was answered in time is the response (see the module docstring); it stops
            # at the first sample cut, so reply i is still sample i (the cache keys on that)
            pass
        return LLMResponse(replies=tuple(replies), backend=self.name, model=model)

    def _request_kwargs(
        self, request: LLMRequest, model: str, n: int, seed: int | None, style: ConstraintStyle
    ) -> dict[str, Any]:
        kwargs: dict[str, Any] = {
            "model": model,
            "messages": [
                {"role": "system", "content": request.system},
                {"role": "user", "content": request.user},
            ],
            "temperature": request.temperature,
            "max_tokens": request.max_tokens,
        }
        if n > 1:
            kwargs["n"] = n
        if seed is not None:
            kwargs["seed"] = seed
        if request.constraint is not None:
            if style == "json_schema":
                kwargs["response_format"] = {
                    "type": "json_schema",
                    "json_schema": {
                        "name": request.constraint.name,
                        "schema": request.constraint.json_schema(),
                        "strict": self._json_schema_strict,
                    },
                }
            else:
                kwargs["extra_body"] = {"grammar": request.constraint.gbnf}
        return kwargs

    def _call(self, request: LLMRequest, model: str, n: int, seed: int | None) -> list[LLMReply]:
        """One request's replies (:meth:`send`); until the server has answered a constrained
        request, a refused constraint is sent once more in the other style, which the run
        then keeps, saying so in one line (:mod:`~stalm.llm.backends.constraint_styles`)."""
        style = self._constraint_style
        if request.constraint is None or self._style_taken or self._is_openai:
            return self.send(request, model, n, seed, style)  # OpenAI's API takes json_schema
        try:
            replies = self.send(request, model, n, seed, style, refusable=True)
        except ConstraintRefused as refused:
            other = other_style(style)
            try:
                replies = self.send(request, model, n, seed, other, refusable=True)
            except ConstraintRefused as again:
                raise both_refused(self._describe(model), refused, again) from None
            with self._lock:
                switched, self._constraint_style = self._constraint_style != other, other
            if switched:
                warnings.warn(switched_notice(self.url, refused, other), StalmWarning, 2)
        self._style_taken = True
        return replies

    def send(
        self,
        request: LLMRequest,
        model: str,
        n: int,
        seed: int | None,
        style: ConstraintStyle,
        *,
        refusable: bool = False,
    ) -> list[LLMReply]:
        """One HTTP request (with retries) -> its choices as replies, the constraint sent in
        ``style``; :class:`DeadlinePassed` when the request's deadline comes first (see the
        module docstring). ``refusable``: a status with which a server refuses a constraint
        (:data:`REFUSALS`) raises :class:`ConstraintRefused` at once, unretried."""
        import openai

        kwargs = self._request_kwargs(request, model, n, seed, style)
        where = self._describe(model)
        deadline = request.deadline
        last_problem = ""
        for attempt in range(self._retry.max_attempts):
            left = time_left(deadline)
            if left is not None and left <= 0:
                raise DeadlinePassed
            timeout_s = self._timeout_s if left is None else min(self._timeout_s, left)
            started = time.perf_counter()
            retry_after: float | None = None
            try:
                completion = run_until(
                    functools.partial(
                        self._client.chat.completions.create, **kwargs, timeout=timeout_s
                    ),
                    deadline,
                )
            except openai.APITimeoutError:
                left = time_left(deadline)
                if left is not None and left <= 0.05:
                    raise DeadlinePassed from None
                last_problem = f"no answer within {timeout_s:g} s"
            except openai.APIConnectionError as error:
                raise StalmError(
                    f"cannot reach {where}: {error.__cause__ or error} (is the server running "
                    f"and is {BASE_URL_ENV} right?)"
                ) from error
            except openai.APIStatusError as error:
                status = error.status_code
                if refusable and refuses_constraint(status, str(error.message)):
                    raise ConstraintRefused(style, status, str(error.message)) from None
                if status in RETRYABLE_STATUS or status >= 500:
                    last_problem = f"HTTP {status}: {error.message}"
                    retry_after = retry_after_s(error)
                else:
                    raise self._status_error(error, where) from error
            except openai.OpenAIError as error:
                raise StalmError(
                    f"{where} answered with something that is not a chat completion: {error}"
                ) from error
            except ValueError as error:  # the body is not JSON (json.JSONDecodeError)
                raise StalmError(
                    f"{where} answered with malformed JSON, not a chat completion ({error})"
                ) from None
            else:
                return chat_replies(
                    completion,
                    request,
                    where,
                    time.perf_counter() - started,
                    json_schema=style == "json_schema",
                )
            if attempt + 1 < self._retry.max_attempts:
                delay = self._retry.delay_s(attempt, retry_after)
                left = time_left(deadline)
                if left is not None and delay >= left:
                    raise DeadlinePassed  # the backoff would outlast the trial's budget
                self._sleep(delay)
        raise StalmError(f"{where} failed {self._retry.max_attempts} times; last: {last_problem}")

    def _status_error(self, error: openai.APIStatusError, where: str) -> StalmError:
        status = error.status_code
        if status in (401, 403):
            names = f"{API_KEY_ENV} or {OPENAI_KEY_ENV}" if self._is_openai else API_KEY_ENV
            return StalmError(f"{where} rejected the API key (HTTP {status}); set {names}")
        if status == 404:
            return StalmError(
                f"{where} has no such model or path (HTTP 404: {error.message}); check the "
                f"model name and that the base URL ends in /v1"
            )
        return StalmError(f"{where} refused the request (HTTP {status}): {error.message}")
