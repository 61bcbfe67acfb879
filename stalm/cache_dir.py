"""Where stalm keeps what it derives and may reuse: roadmaps, the reply cache, model files.

One folder for all of them, ``$STALM_CACHE_DIR`` if set (tests point it at a temporary
folder), else ``~/.cache/stalm``; each user of it keeps its own subfolder or file. Like
:mod:`stalm.errors`, this module sits below every layer, so each layer can ask it.
"""

from __future__ import annotations

import os
from pathlib import Path

CACHE_DIR_ENV = "STALM_CACHE_DIR"


def stalm_cache_dir() -> Path:
    """``$STALM_CACHE_DIR`` (with ``~`` expanded), else ``~/.cache/stalm``."""
    directory = os.environ.get(CACHE_DIR_ENV)
    return Path(directory).expanduser() if directory else Path.home() / ".cache" / "stalm"
