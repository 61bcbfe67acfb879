"""The pure helpers the text-side CLI commands will print with."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stalm.cli.text_commands import format_parsed_reply_json, format_prompt, parse_reply_file
from stalm.errors import StalmError
from stalm.llm.prompt import build_prompt

from .scenarios import FIGURE13_GOAL, FIGURE13_INIT, FIGURE13_VOCABULARY, P3

DATA = Path(__file__).parent / "data"
GOLDEN = Path(__file__).parent / "golden" / "p5_figure13_prompt.txt"


def test_parsed_reply_json_round_trips() -> None:
    parsed = parse_reply_file(DATA / "figure09_p3_reply.txt", P3)
    text = format_parsed_reply_json(parsed)
    assert json.loads(text) == parsed.to_json()
    assert '\n  "plan": [\n' in text


def test_missing_reply_file_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(StalmError, match="does not exist"):
        parse_reply_file(tmp_path / "nope.txt", P3)


def test_undecodable_reply_file_is_a_user_error(tmp_path: Path) -> None:
    path = tmp_path / "reply.txt"
    path.write_bytes(b"plan = [\xff\xfe]")
    with pytest.raises(StalmError, match="cannot read reply file"):
        parse_reply_file(path, P3)


def test_prompt_is_printed_as_the_paper_shows_it() -> None:
    prompt = build_prompt(FIGURE13_VOCABULARY, FIGURE13_INIT, FIGURE13_GOAL)
    assert format_prompt(prompt) == GOLDEN.read_text(encoding="utf-8")
