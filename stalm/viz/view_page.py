"""``stalm view``'s page: one self-contained HTML file that opens offline in any browser.

The 3D scene is drawn by plotly.js, which the ``plotly`` package on PyPI ships inside its
wheel: the page embeds it whole (``get_plotlyjs``), so it needs no network, no CDN and no
JavaScript toolchain to build, and one ``pip install`` brings a version-pinned, widely used
library. Plotly gives, out of the box, what a plan viewer needs from a 3D library: WebGL
triangle meshes with per-face colours and lighting, lines for the arm, an orbiting camera
(turntable drag, zoom, pan, reset) and hover labels. The timeline (play, pause, step to an
action, a slider) is a few lines of page script that move the meshes with ``Plotly.restyle``.
three.js (from npm) would make a smaller page (~0.7 MB instead of plotly.js's ~4.8 MB) but
would have to be vendored into this repository or fetched by an npm step at install time,
and its camera controls and UI written here; a ~5 MB file that loads in a second was judged
the better trade for a page written once per solve.

The page's data (:func:`stalm.viz.view_data.view_data`) is embedded as JSON; the page script
builds every table from it with ``textContent``, so text from a result file (a model's
unreadable reply, a reason) is never interpreted as HTML.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path
from typing import Any

from stalm.errors import StalmError
from stalm.files import write_replacing

PAGE_TITLE = "stalm view"


def _embedded_json(data: Any) -> str:
    """JSON safe inside a ``<script>`` element: ``</`` cannot close it (``<\\/`` parses back
    to ``</`` in JSON), nor can the line separators old parsers stumble on."""
    text = json.dumps(data, separators=(",", ":"), allow_nan=False)
    return (
        text.replace("</", "<\\/")
        .replace("<!--", "<\\u0021--")
        .replace("\u2028", "\\u2028")
        .replace("\u2029", "\\u2029")
    )


def _asset(name: str) -> str:
    return resources.files("stalm.viz").joinpath(name).read_text(encoding="utf-8")


def render_page(data: dict[str, Any]) -> str:
    """The whole page as one HTML string (plotly.js, styles, script and data inline)."""
    try:
        from plotly.offline import get_plotlyjs
    except ImportError:  # pragma: no cover - plotly is a dependency of stalm
        raise StalmError(
            "the page needs the 'plotly' package: pip install plotly (or reinstall stalm)"
        ) from None
    title = f"{PAGE_TITLE}: {data.get('problem', '')} with {data['result'].get('planner')}"
    title = title.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en">',
            "<head>",
            '<meta charset="utf-8">',
            f"<title>{title}</title>",
            f"<style>{_asset('view_page.css')}</style>",
            f"<script>{get_plotlyjs()}</script>",
            "</head>",
            "<body>",
            _asset("view_page.html"),
            f'<script type="application/json" id="stalm-data">{_embedded_json(data)}</script>',
            f"<script>{_asset('view_page.js')}</script>",
            "</body>",
            "</html>",
        ]
    )


def write_page(data: dict[str, Any], path: Path) -> int:
    """Write the page to ``path``; its size in bytes. A path that cannot be written is a
    StalmError naming it."""
    payload = render_page(data).encode("utf-8")
    try:
        write_replacing(path, payload)  # all or nothing: a full disk keeps the old page
    except OSError as error:
        raise StalmError(f"{path}: cannot write the page ({error.strerror or error})") from None
    return len(payload)
