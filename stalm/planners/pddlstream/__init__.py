"""PDDLStream's adaptive algorithm (Garrett et al., 2020) as a baseline, without PDDLStream.

Continuous values (poses, grasps, motions) are PDDL objects produced by streams built on the
domain's samplers ψ; Fast Downward searches the strict PDDL abstraction over them
(:mod:`.pddl_text`); the adaptive loop (:mod:`.adaptive`) adds optimistic objects for stream
instances not yet evaluated, evaluates the ones a plan needs, and feeds failures back.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from stalm.planners.pddlstream.adaptive import AdaptiveSettings
from stalm.planners.pddlstream.planner import PDDLStreamPlanner
from stalm.trial.result import Planner

if TYPE_CHECKING:
    from stalm.settings.tree import RunSettings

__all__ = ["AdaptiveSettings", "PDDLStreamPlanner", "build_pddlstream_adaptive"]


def build_pddlstream_adaptive(
    settings: RunSettings, progress: Callable[[str], None] | None
) -> Planner:
    """The registry's builder (what :class:`PDDLStreamPlanner` reads of the tree, it says)."""
    return PDDLStreamPlanner(settings, progress)
