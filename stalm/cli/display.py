"""Text that came from outside stalm, made safe to print.

Replies, server messages, problem files and result files are not ours: printed through Rich,
a ``[/]`` or ``[bold]`` in them is read as markup (a MarkupError crash, or bracketed text
silently dropped), and an escape code in them would drive the user's terminal. Every such
text goes through :func:`shown` (for Rich, which also escapes markup), :func:`printable`
(for plain output) or :func:`json_printable` (for JSON) before it is printed; stalm's own
markup around it stays live.
"""

from __future__ import annotations

import re

from rich.markup import escape

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u200b-\u200f\u202a-\u202e\u2066-\u2069]")
"""C0/C1 control characters except tab and newline, and the invisible bidirectional and
zero-width marks that can make printed text read differently from what it is."""


def printable(text: object) -> str:
    """``str(text)`` with control characters shown as ``\\xNN`` / ``\\uNNNN`` escapes."""
    return _CONTROL.sub(_visible, str(text))


def shown(text: object) -> str:
    """:func:`printable` text with Rich markup escaped: safe inside a Rich markup string."""
    return escape(printable(text))


def json_printable(encoded: str) -> str:
    """JSON text with every control character as a ``\\uXXXX`` escape (still valid JSON,
    decoding to the same strings: JSON text has such characters only inside strings)."""
    return _CONTROL.sub(lambda match: f"\\u{ord(match.group()):04x}", encoded)


def _visible(match: re.Match[str]) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code <= 0xFF else f"\\u{code:04x}"
