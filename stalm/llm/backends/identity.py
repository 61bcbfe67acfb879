"""Whose replies these are: a backend's provider and server, read from a spec without building it.

A model name alone does not say who answered: any OpenAI-compatible server may call its model
``gpt-4-turbo-2024-04-09``. The reply cache therefore keys a reply by the backend's identity --
its provider and, for a server, its base URL in one normal form -- as well as by the model.
:func:`spec_identity` reads the identity a ``--llm`` spec names without
building the backend: no client, no key, no model loaded, nothing contacted, so a rerun can
say which model its record names and replay that model's cached replies while leaving its
server alone. :class:`CacheOnlyBackend` is that: the identity of a backend which is never
asked.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from stalm.errors import StalmError
from stalm.llm.backends.base import LLMBackend, LLMRequest, LLMResponse
from stalm.llm.backends.openai_compatible import (
    BASE_URL_ENV,
    MODEL_ENV,
    OPENAI_DEFAULT_BASE_URL,
    SERVER_PROVIDER,
    server_url,
)

EMBEDDED_PROVIDER = "embedded"


@dataclass(frozen=True)
class BackendIdentity:
    """A backend's provider, server (None for the embedded model) and model (None when the
    spec leaves it to the server's first listed model, which only asking the server tells)."""

    provider: str
    url: str | None
    model: str | None

    @property
    def key(self) -> str:
        """What the reply cache keys by (with the model)."""
        return self.provider if self.url is None else f"{self.provider} {self.url}"

    def describe(self) -> str:
        """``model 'M' on URL`` or ``the embedded model 'M'``, for a console line."""
        model = repr(self.model) if self.model else "(the server's first listed model)"
        if self.url is None:
            return f"the embedded model {model}"
        return f"model {model} on {self.url}"


def identity_of(backend: LLMBackend) -> str:
    """The cache key of ``backend``'s identity; a backend without one (a test double, a
    user's own class) is known by its name."""
    identity = getattr(backend, "identity", None)
    return identity if isinstance(identity, str) and identity else backend.name


def spec_identity(spec: str | None) -> BackendIdentity:
    """The identity of the backend ``make_backend(spec)`` builds, without building it."""
    from stalm.llm.backends import parsed_spec  # the one reading of a spec

    parsed = parsed_spec(spec)
    if parsed.embedded is not None:
        return BackendIdentity(EMBEDDED_PROVIDER, None, embedded_model_name(parsed.embedded))
    env_url = os.environ.get(BASE_URL_ENV) or os.environ.get("OPENAI_BASE_URL")
    url = parsed.base_url or env_url or OPENAI_DEFAULT_BASE_URL
    model = parsed.model or os.environ.get(MODEL_ENV) or None
    return BackendIdentity(SERVER_PROVIDER, server_url(url), model)


def embedded_model_name(model: str) -> str:
    """The model name the embedded backend gives ``model`` (a packaged name or a file)."""
    if model.endswith(".gguf") or os.sep in model:
        return Path(model).expanduser().name.removesuffix(".gguf")
    from stalm.llm.backends.embedded_models import EMBEDDED_MODELS

    info = EMBEDDED_MODELS.get(model)
    if info is None:
        raise StalmError(
            f"unknown embedded model {model!r} (available: {', '.join(EMBEDDED_MODELS)})"
        )
    return info.display_name


class CacheOnlyBackend:
    """The backend a spec names, known by its identity only and never asked.

    Behind a :class:`~stalm.llm.cache.CachedBackend` in replay mode it lets a rerun serve the
    replies a record's model gave from the reply cache while its server (named by the record,
    not by the user) is never contacted and no key is read. Asked anything, it raises.
    """

    def __init__(self, identity: BackendIdentity) -> None:
        self._identity = identity

    @property
    def name(self) -> str:
        return self._identity.provider

    @property
    def identity(self) -> str:
        return self._identity.key

    @property
    def model(self) -> str:
        if self._identity.model is None:
            raise StalmError(
                f"the record names no model for {self._identity.url}, so its replies cannot "
                "be found in the reply cache; name a model with --llm or $STALM_LLM"
            )
        return self._identity.model

    @property
    def description(self) -> str:
        return f"{self._identity.describe()}, answered from the reply cache only"

    def complete(self, request: LLMRequest) -> LLMResponse:
        raise StalmError(
            f"{self._identity.describe()} is not contacted: it is named by the record, not by "
            "you; name a model with --llm or $STALM_LLM to ask one"
        )
