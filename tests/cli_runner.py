"""Running the ``stalm`` command in-process, as the CLI tests do."""

from __future__ import annotations

import sys

import pytest

from stalm.cli.main import main


def run_cli(monkeypatch: pytest.MonkeyPatch, *args: str) -> int:
    """``stalm ARGS...`` in this process; its exit code (0 when it returns normally)."""
    monkeypatch.setattr(sys, "argv", ["stalm", *args])
    try:
        main()
    except SystemExit as done:
        return int(done.code or 0)
    return 0
