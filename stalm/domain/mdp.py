"""The G-TAMP MDP of §3.1 and §4.1: legal discrete actions, ψ, the transition T and reward R.

:class:`Domain` ties one problem to one :class:`~stalm.world.scene.Sim`. ``sample`` draws κ
for a discrete action (ψ, with the operator's number of tries); ``step`` applies a sampled
action deterministically (T) and scores it (R); ``sample_and_step`` does both and turns an
infeasible draw into the absorbing failure outcome (s' = s, reward -6).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stalm.domain.actions import DiscreteAction, Open, Pick, Place
from stalm.domain.outcome import Infeasibility, Outcome
from stalm.domain.params import Action, OpenParams, PickParams, PlaceParams
from stalm.domain.samplers import Samplers, SamplerSettings
from stalm.domain.vocabulary import Vocabulary
from stalm.geometry.transforms import wrap_angle
from stalm.motion.base_motion import BasePlanner
from stalm.motion.roadmap import RoadmapSettings
from stalm.world.problem import Problem
from stalm.world.relations import at_position
from stalm.world.scene import Sim
from stalm.world.state import RobotConf, State


@dataclass(frozen=True)
class RewardSettings:
    """R of §4.1 (+3 per goal AtPosition an action makes true, -6 infeasible), -3 per goal
    AtPosition an action makes false (potential-based shaping, beyond the paper) and the
    authors' +100 at the goal; all configurable."""

    goal_atom: float = 3.0
    goal_atom_lost: float = 3.0
    """Taken back per goal conjunct an action makes false (0 gives the authors' farmable +3)."""
    infeasible: float = -6.0
    goal: float = 100.0


@dataclass
class DomainCounters:
    """How much work the domain did; planners report these."""

    transitions: int = 0
    samples: int = 0
    infeasible: int = 0


@dataclass
class Domain:
    """One problem's MDP over one simulator."""

    problem: Problem
    sim: Sim
    sampler_settings: SamplerSettings = field(default_factory=SamplerSettings)
    reward_settings: RewardSettings = field(default_factory=RewardSettings)
    roadmap_settings: RoadmapSettings = field(default_factory=RoadmapSettings)
    counters: DomainCounters = field(default_factory=DomainCounters)

    def __post_init__(self) -> None:
        self.vocabulary = Vocabulary.from_problem(self.problem)
        self.base_planner = BasePlanner(
            self.sim, self.roadmap_settings, engine=self.sampler_settings.engine
        )
        self.samplers = Samplers(self.sim, self.base_planner, self.sampler_settings)
        self._all_actions = self.vocabulary.all_discrete_actions()

    @staticmethod
    def create(problem: Problem, **settings: object) -> Domain:
        """A domain with its own fresh simulator."""
        return Domain(problem, Sim(problem.spec), **settings)  # type: ignore[arg-type]

    def close(self) -> None:
        self.sim.close()

    # ------------------------------------------------------------------ symbols
    def precondition_failure(self, state: State, action: DiscreteAction) -> str | None:
        """Why the symbolic precondition of ``action`` is false in ``state`` (None if true)."""
        kind = self.vocabulary.kind_of
        if isinstance(action, Pick):
            if kind(action.obj) != "movable":
                return f"'{action.obj}' is not a movable object"
            if not state.hand_empty:
                return f"the hand already holds '{state.held.obj}'" if state.held else "hand busy"
            return None
        if isinstance(action, Place):
            if kind(action.obj) != "movable":
                return f"'{action.obj}' is not a movable object"
            if state.held is None or state.held.obj != action.obj:
                return f"the robot is not holding '{action.obj}'"
            if action.direction == "on":
                if kind(action.ref) != "region":
                    return f"'{action.ref}' is not a region"
            elif kind(action.ref) != "movable" or action.ref == action.obj:
                return f"'{action.ref}' is not another movable object"
            return None
        if kind(action.door) != "door":
            return f"'{action.door}' is not a door"
        if state.is_open(action.door):
            return f"'{action.door}' is already open"
        if not state.hand_empty:
            return "the hand is not empty"
        return None

    def legal_actions(self, state: State) -> tuple[DiscreteAction, ...]:
        """Every discrete action whose symbolic precondition holds (no geometry)."""
        return tuple(a for a in self._all_actions if self.precondition_failure(state, a) is None)

    def is_goal(self, state: State) -> bool:
        spec = self.problem.spec
        return all(at_position(spec, state, g.obj, g.direction, g.ref) for g in self.problem.goal)

    def goal_atoms_true(self, state: State) -> int:
        spec = self.problem.spec
        return sum(at_position(spec, state, g.obj, g.direction, g.ref) for g in self.problem.goal)

    # ------------------------------------------------------------------ ψ, T, R
    def sample(
        self, state: State, action: DiscreteAction, rng: np.random.Generator
    ) -> Action | Infeasibility:
        """ψ(s, α(δ)): a feasible κ for ``action`` in ``state``, or why there is none."""
        self.counters.samples += 1
        why = self.precondition_failure(state, action)
        if why is not None:
            return Infeasibility("precondition", why)
        if isinstance(action, Pick):
            params: PickParams | PlaceParams | OpenParams | Infeasibility = self.samplers.pick(
                state, action, rng
            )
        elif isinstance(action, Place):
            params = self.samplers.place(state, action, rng)
        else:
            params = self.samplers.open(state, action, rng)
        if isinstance(params, Infeasibility):
            return params
        return Action(action, params)

    def next_state(self, state: State, action: Action) -> State:
        """T(s, α(δ, κ)) for a κ drawn in ``state``: deterministic, no collision checks."""
        params = action.params
        discrete = action.discrete
        if isinstance(params, PickParams):
            assert isinstance(discrete, Pick)
            stand = params.base_path.corners[-1]
            offset = state.pose(discrete.obj).yaw - stand[2]
            return state.with_changes(
                remove=discrete.obj,
                robot=self._carry(stand),
                held=params.grasp,
                held_yaw_offset=wrap_angle(offset),
            )
        if isinstance(params, PlaceParams):
            assert isinstance(discrete, Place)
            stand = params.base_path.corners[-1]
            return state.with_changes(
                poses={discrete.obj: params.placement},
                robot=self._carry(stand),
                held=None,
                held_yaw_offset=0.0,
            )
        assert isinstance(discrete, Open)
        return state.with_changes(
            robot=self._carry(params.base_path.corners[-1]), open_door=discrete.door
        )

    def _carry(self, stand: tuple[float, float, float]) -> RobotConf:
        """The robot at ``stand`` with its arm folded, as it drives after every action."""
        carry = self.sim.robot.carry_conf
        return RobotConf.make(stand, carry[0], carry[1:])

    def reward(self, state: State, next_state: State) -> float:
        """+3 per goal conjunct made true, -3 per goal conjunct made false, +100 at the goal.

        The -3 makes the +3 a potential-based shaping (Φ = 3 · goal conjuncts true): a path's
        return is its net goal progress, so picking an object off its goal and placing it
        back earns nothing and cannot be farmed, and the optimal plans are unchanged
        (potential-based shaping, Ng et al. 1999).
        """
        spec = self.problem.spec
        gained = lost = 0
        for g in self.problem.goal:
            before = at_position(spec, state, g.obj, g.direction, g.ref)
            after = at_position(spec, next_state, g.obj, g.direction, g.ref)
            gained += after and not before
            lost += before and not after
        rewards = self.reward_settings
        value = rewards.goal_atom * gained - rewards.goal_atom_lost * lost
        if self.is_goal(next_state):
            value += self.reward_settings.goal
        return float(value)

    def step(self, state: State, action: Action) -> Outcome:
        """Apply a feasible sampled action: s', r and whether the goal is reached."""
        self.counters.transitions += 1
        nxt = self.next_state(state, action)
        return Outcome(nxt, self.reward(state, nxt), True, None, self.is_goal(nxt))

    def infeasible(self, state: State, why: Infeasibility) -> Outcome:
        """The absorbing failure: s' = s and the -6 penalty."""
        self.counters.transitions += 1
        self.counters.infeasible += 1
        return Outcome(state, self.reward_settings.infeasible, False, why, False)

    def sample_and_step(
        self, state: State, action: DiscreteAction, rng: np.random.Generator
    ) -> tuple[Action | None, Outcome]:
        """Draw κ and apply it; an infeasible draw yields the failure outcome."""
        drawn = self.sample(state, action, rng)
        if isinstance(drawn, Infeasibility):
            return None, self.infeasible(state, drawn)
        return drawn, self.step(state, drawn)
