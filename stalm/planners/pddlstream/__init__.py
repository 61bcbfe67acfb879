"""PDDLStream's adaptive algorithm (Garrett et al., 2020) as a baseline, without PDDLStream.

Continuous values (poses, grasps, motions) are PDDL objects produced by streams built on the
domain's samplers ψ; Fast Downward searches the strict PDDL abstraction over them
(:mod:`.pddl_text`); the adaptive loop (:mod:`.adaptive`) adds optimistic objects for stream
instances not yet evaluated, evaluates the ones a plan needs, and feeds failures back.
"""

from __future__ import annotations

from stalm.planners.pddlstream.adaptive import AdaptiveSettings
from stalm.planners.pddlstream.planner import PDDLStreamPlanner

__all__ = ["AdaptiveSettings", "PDDLStreamPlanner"]
