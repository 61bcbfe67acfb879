"""``--gif``: a size option, fewer frames rendered, progress while it renders (issue 42,
finding 3). The animation took 25 of a P2 run's 32 s, silently, at a fixed 480x240: it now
renders one motion frame in :data:`FRAME_STRIDE` and each action's last, at ``--gif-size``.
How much faster is measured by ``benchmarks/bench_gif.py``, not asserted here."""

from __future__ import annotations

from pathlib import Path

import pytest
from PIL import Image

from stalm.viz.animate import FRAME_STRIDE, kept_frames, plan_motion, write_animation
from tests.cli_runner import run_cli
from tests.world.test_animation import two_p2_actions


def test_kept_frames_are_the_first_one_in_a_stride_and_each_action_s_last() -> None:
    actions = [-1, 0, 0, 0, 0, 0, 0, 1, 1, 1]
    assert kept_frames(actions, 4) == frozenset({0, 4, 6, 8, 9})
    assert kept_frames(actions, 1) == frozenset(range(len(actions)))


def test_the_animation_renders_a_fraction_of_the_motion_at_its_size(
    domain_factory, tmp_path: Path
) -> None:
    domain = domain_factory("P2")
    pairs = two_p2_actions(domain)
    start = domain.problem.initial_state
    motion = list(plan_motion(domain.sim, start, pairs))
    heard: list[tuple[int, int]] = []
    path = tmp_path / "plan.gif"
    frames = write_animation(
        domain.sim, start, pairs, path, size=40, progress=lambda *a: heard.append(a)
    )
    assert frames == len(kept_frames(motion, FRAME_STRIDE))
    assert frames * 3 <= len(motion)  # a third of the frames or fewer to render
    assert heard == [(n, frames) for n in range(1, frames + 1)]
    with Image.open(path) as gif:
        assert gif.size == (80, 40) and gif.n_frames == frames


@pytest.fixture(autouse=True)
def _no_llm_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("STALM_LLM", "STALM_LLM_BASE_URL", "STALM_LLM_MODEL", "OPENAI_API_KEY"):
        monkeypatch.delenv(name, raising=False)


def test_stalm_solve_gif_size_sets_the_views_pixels(monkeypatch, tmp_path: Path) -> None:
    path = tmp_path / "p2.gif"
    code = run_cli(monkeypatch, "solve", "P2", "--gif", str(path), "--gif-size", "32")
    assert code == 0
    with Image.open(path) as gif:
        assert gif.size == (64, 32)


def test_a_gif_size_out_of_range_is_refused_before_solving(monkeypatch, capsys, tmp_path) -> None:
    path = tmp_path / "p2.gif"
    code = run_cli(monkeypatch, "solve", "P2", "--gif", str(path), "--gif-size", "8")
    assert code == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "--gif-size must be between 16 and 4096 pixels, got 8" in err
    assert "solved" not in err and not path.exists()
