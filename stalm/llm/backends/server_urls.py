"""A server's base URL: checked, in the one form that names it, and whether it is OpenAI's."""

from __future__ import annotations

import os
from urllib.parse import urlsplit

from stalm.errors import StalmError


def server_url(url: str) -> str:
    """``url`` in the form that names one server: scheme and host in lower case, the port
    only when it is not the scheme's default, no trailing slash (the reply cache keys by it)."""
    parts = urlsplit(url.strip())
    scheme, host = parts.scheme.lower(), (parts.hostname or "").lower()
    default = {"http": 80, "https": 443}.get(scheme)
    port = f":{parts.port}" if parts.port is not None and parts.port != default else ""
    if ":" in host:  # an IPv6 literal keeps its brackets
        host = f"[{host}]"
    return f"{scheme}://{host}{port}{parts.path.rstrip('/')}"


def is_openai_api(url: str) -> bool:
    """True only for OpenAI's own API over HTTPS (not a look-alike host, not plain HTTP)."""
    parts = urlsplit(url)
    return parts.scheme == "https" and parts.hostname == "api.openai.com"


def check_base_url(url: str) -> str:
    """``url`` if it is an http(s) URL with a host, else a StalmError naming it."""
    try:
        parts = urlsplit(url)
        host = parts.hostname
        parts.port  # noqa: B018 - raises ValueError for a port that is not a number
    except ValueError as error:
        raise StalmError(f"base URL {url!r} is not a valid URL ({error})") from None
    if parts.scheme not in ("http", "https") or not host:
        raise StalmError(
            f"base URL {url!r} is not an http(s) URL with a host, e.g. http://127.0.0.1:8080/v1"
        )
    return url


def env(*names: str) -> str | None:
    for name in names:
        value = os.environ.get(name)
        if value:
            return value
    return None
