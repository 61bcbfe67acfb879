"""Text from records put into a Markdown table cell without breaking the table.

Row labels, problem names and kinds come from results files, which anyone may have written:
a ``|`` in an arm's label split its row into extra columns, and a newline ended the row. A
cell's text keeps its words, with ``|`` and ``\\`` escaped and every run of white space (line
breaks included) one space.
"""

from __future__ import annotations


def cell(text: object) -> str:
    """``text`` as the content of one Markdown table cell (see the module docstring)."""
    flat = " ".join(str(text).split())
    return flat.replace("\\", "\\\\").replace("|", "\\|")
