"""``stalm view``'s page in a real headless browser: Chromium (Debian's package; ``.ci/run``
installs it) driven by Playwright, pointed at the installed binary (Playwright's own browser
download is not used). The page must load with no console error, draw the scene, move it
along the timeline, play by itself, and show the per-step record.

Skipped only when no Chromium is installed (set ``$STALM_CHROMIUM`` to use another binary).
"""

from __future__ import annotations

import io
import json
import os
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from stalm.viz.view_data import view_data
from stalm.viz.view_page import write_page

DATA = Path(__file__).parent / "data"
BACKGROUND = (250, 250, 250)
"""The scene's paper colour (view_page.js)."""


def _chromium() -> str | None:
    configured = os.environ.get("STALM_CHROMIUM")
    if configured:
        return configured
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


CHROMIUM = _chromium()
pytestmark = [
    pytest.mark.skipif(
        CHROMIUM is None,
        reason="no Chromium installed (apt-get install chromium; .ci/run installs it)",
    ),
    pytest.mark.slow,  # 20-45 s: the browser starts, parses plotly.js and renders in software
]


@pytest.fixture(scope="module")
def pages(tmp_path_factory: pytest.TempPathFactory, problems) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("pages")
    made = {}
    for name, path in (
        ("steps", DATA / "p2_steps_result.json"),
        ("old", Path(__file__).parent.parent / "planners" / "data" / "p2_result.json"),
    ):
        data = view_data(problems["P2"], json.loads(path.read_text()), path.name)
        made[name] = folder / f"{name}.html"
        write_page(data, made[name])
    return made


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(
            executable_path=CHROMIUM,
            # WebGL without a GPU: Chromium's software rasteriser
            args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
        )
        try:
            yield launched
        finally:
            launched.close()


def _open(browser, page_file: Path) -> tuple[object, list[str]]:
    page = browser.new_page(viewport={"width": 1280, "height": 900})
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(page_file.as_uri())
    page.wait_for_selector('body[data-ready="1"]', timeout=60_000)
    return page, errors


def _scene_pixels(page) -> np.ndarray:
    shot = page.locator("#stalm-scene").screenshot()
    return np.asarray(Image.open(io.BytesIO(shot)).convert("RGB"), dtype=np.int16)


def _drawn(page, frame: int) -> None:
    page.evaluate(f"window.stalmView.setFrame({frame})")
    page.wait_for_function(f"document.body.dataset.rendered === '{frame}'", timeout=30_000)


def test_the_page_draws_the_scene_and_the_timeline_moves_it(browser, pages) -> None:
    page, errors = _open(browser, pages["steps"])
    try:
        frames = page.evaluate("window.stalmView.frames")
        assert frames > 40
        first = _scene_pixels(page)
        drawn = np.abs(first - np.array(BACKGROUND)).max(axis=2) > 30
        assert drawn.mean() > 0.2, "the scene (floor, walls, counters) covers the view"
        # mid-plan the robot, the door and the carried objects stand elsewhere
        _drawn(page, frames // 2)
        middle = _scene_pixels(page)
        changed = np.abs(middle - first).max(axis=2) > 30
        assert changed.sum() > 300, "moving the timeline changes the picture"
        label = page.text_content("#frame-label")
        assert f"frame {frames // 2 + 1}/{frames}" in label and "action" in label
        assert re.search(r", [\d.]+ s of [\d.]+ s robot time: ", label)  # the export's timing
        # the plan table follows: the current action's row is highlighted
        assert page.locator("#plan tbody tr.current").count() == 1
        # step to an action: to the first frame of the next one
        page.click("#next-action")
        page.wait_for_function(
            f"document.body.dataset.rendered === String(window.stalmView.frame) "
            f"&& window.stalmView.frame > {frames // 2}"
        )
        # play runs by itself, pause stops it
        _drawn(page, 0)
        page.click("#play")
        page.wait_for_function("window.stalmView.frame >= 3", timeout=30_000)
        page.click("#play")
        assert not page.evaluate("window.stalmView.playing")
        # the search, step by step: four steps, failed task-plan steps, warm-started nodes
        assert page.locator("#steps details.step").count() == 4
        assert page.locator("#steps .chip.failed").count() >= 1
        assert page.locator("#steps span.warm").count() >= 1
        assert errors == []
    finally:
        page.close()


def test_an_old_result_page_loads_and_says_what_is_missing(browser, pages) -> None:
    page, errors = _open(browser, pages["old"])
    try:
        assert "no per-step record" in page.text_content("#notes")
        assert page.locator("#plan tbody tr").count() == 7
        pixels = _scene_pixels(page)
        assert (np.abs(pixels - np.array(BACKGROUND)).max(axis=2) > 30).mean() > 0.2
        assert errors == []
    finally:
        page.close()
