"""Pure helpers behind the text-side commands (show a prompt, parse a saved reply).

The commands themselves (``stalm prompt P5``, ``stalm parse-reply reply.txt P5``) need the
problem loader to turn a problem name into a vocabulary, init and goal; until that API is
settled they are wired in :mod:`stalm.cli.main` by its owner. Everything here takes plain
values, so the wiring is a few lines and the output format is tested on its own.
"""

from __future__ import annotations

import json
from pathlib import Path

from stalm.cli.display import json_printable
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.prompt import Prompt
from stalm.llm.reply_parser import ParsedReply, parse_reply


def format_parsed_reply_json(parsed: ParsedReply) -> str:
    """The parse result as indented JSON (plan, steps, errors with index/raw/message, reason).

    Non-ASCII text stays readable, but control characters the JSON encoder leaves raw (C1
    codes, bidirectional marks) are written as ``\\uXXXX`` escapes: the reply is not ours.
    """
    return json_printable(json.dumps(parsed.to_json(), indent=2, ensure_ascii=False))


def format_prompt(prompt: Prompt) -> str:
    """Both prompt messages under the paper's headings, as the prompt command prints them."""
    return prompt.as_transcript()


def parse_reply_file(reply_path: Path, vocabulary: Vocabulary) -> ParsedReply:
    """Parse a saved reply; a missing or unreadable file is the user's error, not a crash."""
    try:
        text = reply_path.read_text(encoding="utf-8")
    except FileNotFoundError as error:
        raise StalmError(f"reply file {str(reply_path)!r} does not exist") from error
    except (OSError, UnicodeDecodeError) as error:
        raise StalmError(f"cannot read reply file {str(reply_path)!r}: {error}") from error
    return parse_reply(text, vocabulary)
