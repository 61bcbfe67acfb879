"""The Python API: what a script needs to load a problem, build and run a planner, inspect
the result, replay it (:func:`check_physics` then settles the replayed states under gravity,
as ``stalm replay --physics`` does), and plug in its own task-plan proposer.

Everything here is re-exported from the module that owns it, so this file is the one place
to look (and the one the README's examples import from); it imports the planners, so it sits
at the top of the layer order beside the CLI. ``import stalm`` alone stays light.

A planner takes a run's settings tree (:class:`RunSettings`, whose defaults are the ones
``stalm solve`` runs); :func:`with_overrides` sets its dotted keys as ``--set`` does
(``"execution.feedback=true"``) and :func:`with_values` with typed values
(``("execution.feedback", True)``).

A proposer is any object of the :class:`TaskPlanProposer` form: a ``name``, a
``takes_feedback`` flag, and ``propose(request)`` taking a :class:`ProposalRequest` and
giving a :class:`Proposal`; with ``takes_feedback`` true, STaLM's ``request.feedback`` also
says which steps failed.

A problem can be built in Python as well as read from a file: a :class:`ProblemSpec` of
:class:`WallSpec`, :class:`RegionSpec`, :class:`DoorSpec`, :class:`ObjectSpec`,
:class:`RobotSpec` and :class:`GoalSpec` is checked field by field as a problem file is
(:func:`parse_problem` validates a mapping, as loaded from YAML, naming its source in every
error); ``Problem(spec, source)`` is what a planner solves, and
:func:`check_problem_geometry` checks its scene in the simulator as ``stalm solve`` does.
"""

from __future__ import annotations

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.errors import StalmError
from stalm.motion.problem_check import check_problem_geometry
from stalm.planners.registry import build_planner, planners
from stalm.planners.stalm import StalmPlanner
from stalm.proposers.fast_downward import SymbolicProposer
from stalm.proposers.feedback import FailedStep
from stalm.proposers.language_model import LLMProposer
from stalm.proposers.noisy import NoisyProposer
from stalm.proposers.protocol import Proposal, ProposalRequest, TaskPlanProposer
from stalm.settings.io import with_overrides, with_values
from stalm.settings.tree import RunSettings
from stalm.trial.replay import ReplayReport, replay_plan
from stalm.trial.result import PlanResult
from stalm.world.object_spec import ObjectSpec
from stalm.world.physics_check import PhysicsReport, check_physics
from stalm.world.problem import Problem, load_problem
from stalm.world.problem_file import parse_problem
from stalm.world.spec import DoorSpec, GoalSpec, ProblemSpec, RegionSpec, RobotSpec, WallSpec
from stalm.world.state import State

__all__ = [
    "DiscreteAction",
    "DoorSpec",
    "FailedStep",
    "GoalSpec",
    "LLMProposer",
    "NoisyProposer",
    "ObjectSpec",
    "Open",
    "PhysicsReport",
    "Pick",
    "Place",
    "PlanResult",
    "Problem",
    "ProblemSpec",
    "Proposal",
    "ProposalRequest",
    "RegionSpec",
    "ReplayReport",
    "RobotSpec",
    "RunSettings",
    "StalmError",
    "StalmPlanner",
    "State",
    "SymbolicProposer",
    "TaskPlanProposer",
    "WallSpec",
    "build_planner",
    "check_physics",
    "check_problem_geometry",
    "load_problem",
    "parse_problem",
    "planners",
    "replay_plan",
    "with_overrides",
    "with_values",
]
