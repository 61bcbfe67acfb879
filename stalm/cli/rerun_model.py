"""Which model ``stalm rerun`` asks, and where its replies and outputs go.

A record is a file someone may send: it names a model -- often a server, perhaps one with a
key of yours -- and a reply-cache file. Neither is the record's to choose on your machine.
The model a rerun asks is the one the user names: ``--llm``, else
``$STALM_LLM``, else a server in ``$STALM_LLM_BASE_URL``; without one, the record's model is
only replayed from the reply cache (nothing is contacted, no key is read), except the bundled
embedded models, which run in this process and contact nothing. The reply cache is the one
the user names (``--cache-file``, else the default under ``$STALM_CACHE_DIR``), never the
record's. The console names the model and the server used and the record's own.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from stalm.errors import StalmError
from stalm.llm.backends import SPEC_ENV, parsed_spec
from stalm.llm.backends.embedded_models import EMBEDDED_MODELS
from stalm.llm.backends.identity import spec_identity
from stalm.llm.backends.openai_compatible import BASE_URL_ENV
from stalm.llm.cache import check_cache_mode
from stalm.llm.cache_file import default_cache_path
from stalm.settings.tree import LlmSection


def rerun_llm(
    recorded: LlmSection, llm: str | None, cache: str | None, cache_file: Path | None
) -> tuple[LlmSection, str]:
    """The ``llm`` section a rerun runs with and who named its model (``--llm``,
    ``$STALM_LLM``, ``$STALM_LLM_BASE_URL``, ``the record``). Only whether replies were
    constrained is kept from the record: it shapes the prompt, not where anything goes."""
    mode = check_cache_mode(cache or "use")
    ours = LlmSection(
        constrained=recorded.constrained,
        cache=mode,
        cache_file=str(cache_file) if cache_file is not None else None,
    )
    for spec, source in ((llm, "--llm"), (os.environ.get(SPEC_ENV), f"${SPEC_ENV}")):
        if spec and spec.strip():
            parsed_spec(spec)  # an unknown spec is an error before any work
            return replace(ours, backend=spec), source
    if os.environ.get(BASE_URL_ENV):
        return ours, f"${BASE_URL_ENV}"
    spec = recorded.backend
    if spec is None or parsed_spec(spec).embedded in EMBEDDED_MODELS:
        return replace(ours, backend=spec), "the record; bundled, it runs here"
    return replace(ours, backend=spec, cache="replay", from_record=True), "the record"


def model_line(llm: LlmSection, source: str, recorded: LlmSection) -> str:
    """One console line: the model this rerun asks (or replays) and the reply cache it uses
    (record text in it: print it through :func:`~stalm.cli.display.shown`)."""
    where = llm.cache_file or str(default_cache_path())
    used = spec_identity(llm.backend).describe()
    if llm.from_record:
        return (
            f"the record's {used} is not contacted: its replies come from the reply "
            f"cache only ({where}); name a model with --llm or ${SPEC_ENV} to ask one"
        )
    verb = "replaying the replies of" if llm.cache == "replay" else "asking"
    line = f"{verb} {used} ({source}); reply cache {llm.cache}: {where}"
    if recorded.backend is not None and recorded.backend != llm.backend:
        try:
            theirs = spec_identity(recorded.backend).describe()
        except StalmError:
            theirs = repr(recorded.backend[:80])
        line += f"; the record's was {theirs}"
    return line
