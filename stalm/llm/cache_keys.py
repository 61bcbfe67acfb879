"""The reply cache's keys: what makes two requests the same sample.

A key hashes everything that determines a sample's distribution: whose backend it is
(provider and server, :mod:`stalm.llm.backends.identity`), the model, the prompt and the
sampling settings, and nothing machine-specific, so a cache file copied to another machine
hits there for the same server. Keys an older stalm wrote (:func:`legacy_sample_key`) left the
server out. Kept apart from the file (:mod:`stalm.llm.cache_file`) because the key is a
contract of its own: changing it orphans every cache file people hold.
"""

from __future__ import annotations

import hashlib
import json

from stalm.llm.backends.base import LLMRequest

KEY_VERSION = 2
"""The version hashed into every key written now (with the backend's identity)."""
LEGACY_KEY_VERSION = 1
"""The version of keys written before the identity was part of them."""


def prompt_digest(system: str, user: str) -> str:
    """The digest that names a prompt in the cache's ``prompts`` table."""
    return hashlib.sha256(json.dumps([system, user]).encode("utf-8")).hexdigest()


def sample_key(identity: str, model: str, request: LLMRequest, index: int) -> str:
    """The cache key of sample ``index`` of ``request`` sent to ``model`` of the backend
    whose identity is ``identity`` (provider and server).

    ``request.n`` is deliberately absent: sample 3 of a batch of 5 is the same draw as
    sample 3 of a batch of 4.
    """
    return _key(KEY_VERSION, identity, model, request, index)


def legacy_sample_key(backend: str, model: str, request: LLMRequest, index: int) -> str:
    """The key an older stalm gave the sample: the backend's name (``openai-compatible``)
    where the identity is now, so any server's replies under one model name shared it."""
    return _key(LEGACY_KEY_VERSION, backend, model, request, index)


def _key(version: int, who: str, model: str, request: LLMRequest, index: int) -> str:
    fingerprint = request.constraint.fingerprint if request.constraint else None
    material = [
        version,
        who,
        model,
        request.system,
        request.user,
        request.temperature,
        request.max_tokens,
        request.seed,
        fingerprint,
        index,
    ]
    encoded = json.dumps(material, ensure_ascii=False, separators=(",", ":"))
    return hashlib.sha256(encoded.encode("utf-8")).hexdigest()
