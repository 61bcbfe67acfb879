"""The online-planner scaffold, written once: a trial's loop around one method's decisions.

STaLM and the baselines that act online (UCT, UCT-with-Hcount, EP-SayCan,
Iterative-Replanning, LLM-MCTS) all run the same trial: start one wall-clock deadline and one
simulator, repeatedly decide what to execute in the current state and execute it, stop at the
goal, the horizon or the deadline (also when it passes during a predicate computation, which
the deadline bounds), and replay the executed plan in a fresh scene before it counts
(:meth:`Episode.finish`). :class:`OnlinePlanner` is that trial; a method is the part that says
what it decides (:class:`Decider`, made by the planner's ``start``), from what :class:`Trial`
gives it (the bookkeeping of :class:`~stalm.trial.episode.Episode`, the seeded generator, the
search tree kept between real steps, phase timing and progress messages).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from stalm.domain.mdp import Domain
from stalm.domain.params import Action
from stalm.predicates.deadline import DeadlinePassed
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.memo import PredicateMemo
from stalm.progress import Progress, observer_of
from stalm.search import SearchSettings, SearchTree
from stalm.settings.tree import RunSettings
from stalm.trial.details import MethodDetails
from stalm.trial.episode import Episode
from stalm.trial.result import PlanResult, check_seed, check_time_budget
from stalm.world.problem import Problem
from stalm.world.scene import Sim
from stalm.world.scene_build import SceneAbandoned
from stalm.world.state import State

log = logging.getLogger(__name__)
"""Each real step's decision, at INFO (``stalm solve --verbose`` shows them)."""

Decision = tuple[Action, ...] | str
"""What a decision returns: the actions to execute now (none: decide again from the same
state), or a termination ('timeout', 'no_progress') that ends the trial."""


@dataclass
class Trial:
    """One trial in progress, as a method's decisions see it: what the method adds (domain,
    generator, tree, counts) to the :attr:`episode`, the one place to ask what the trial is
    at (problem, state, predicates, deadline)."""

    domain: Domain
    episode: Episode
    rng: np.random.Generator
    seed: int
    reuse_tree: bool = False
    """Keep the executed child's subtree as the next step's tree (:meth:`execute`)."""
    tree: SearchTree | None = None
    """The search tree of the current state, if the method searches (:meth:`tree_at`)."""
    simulations: int = 0
    replans: int = 0
    reused_root_visits: list[int] = field(default_factory=list)
    """Per real step whose tree was kept: the visits its root already had."""

    @property
    def memo(self) -> PredicateMemo:
        """The trial's predicates by state (the episode keeps them)."""
        if self.episode.memo is None:
            raise RuntimeError("the trial's predicates are not set up")
        return self.episode.memo

    @property
    def done(self) -> int:
        """How many actions have been executed."""
        return len(self.episode.executed)

    def within_horizon(self, search: SearchSettings) -> SearchSettings:
        """``search`` looking no further than this trial's horizon (the problem's): a plan
        the tree finds is executed whole, so it must end within the steps the trial has
        left, whatever horizon the method's own settings carry."""
        horizon = self.episode.problem.horizon
        return search if search.horizon == horizon else dataclasses.replace(search, horizon=horizon)

    def share_end(self, share: float) -> float:
        """When a step starting now has spent ``share`` of the trial's remaining time."""
        now = time.monotonic()
        return now + share * max(0.0, self.episode.deadline - now)

    def say(self, message: str) -> None:
        """Report progress to the trial's observer (``stalm solve`` prints it)."""
        self.episode.observer.message(message)

    def phase(self, name: str | None) -> AbstractContextManager[None]:
        """Charge the block's wall time to phase ``name`` (see :meth:`PhaseClock.timed`)."""
        return self.episode.clock.timed(name)

    def tree_at(self, state: State) -> SearchTree:
        """The tree rooted at ``state``: the one kept from the last step if it is rooted
        there, else a new one (kept until an action is executed)."""
        if self.tree is None or self.tree.root != state:
            self.tree = SearchTree.for_root(self.domain, state)
        return self.tree

    def execute(self, action: Action) -> None:
        """Execute a feasible sampled action; with tree reuse, the executed action's child
        becomes the tree's root, with its statistics (the authors' loop)."""
        before = self.episode.state
        self.episode.execute(self.domain, action)
        tree, self.tree = self.tree, None
        after = self.episode.state
        if tree is not None and self.reuse_tree and tree.root == before and after in tree:
            self.tree = tree.subtree(after)
            self.reused_root_visits.append(self.tree.visits(after))
        self.say(f"executed {action.discrete}")


class Decider(Protocol):
    """One method's decisions within one trial (made by :attr:`OnlinePlanner.start`)."""

    def decide(self) -> Decision:
        """What to do in the trial's current state."""
        ...

    def details(self) -> MethodDetails:
        """The method's own record for ``PlanResult.details``."""
        ...


StartSteps = Callable[[Trial], Decider]
"""A method's part of a planner: its decisions for a trial that starts now."""


@dataclass(frozen=True)
class OnlinePlanner:
    """A planner that acts online, composed: the loop of every online method around one
    method's :class:`Decider` (made by ``start``), configured by the run's settings tree.

    The tree's ``samplers``, ``rewards`` and ``predicates`` sections configure the trial's
    domain and predicate engine, ``execution.reuse_tree`` whether the executed child's subtree
    is the next step's tree; the method says whether the predicates include the occlusion
    literals (``occlusion``, which cost motion planning)."""

    name: str
    settings: RunSettings
    start: StartSteps
    progress: Progress | None = None
    occlusion: bool = True

    def solve(self, problem: Problem, seed: int, time_budget_s: float | None = None) -> PlanResult:
        """Plan and execute until the goal, the horizon or the time budget (None: the
        problem's), in a simulator of the trial's own that is always closed.

        Set-up (the scene, the domain, the predicate engine, the method's start) is the
        trial's first phase, 'setup', inside its deadline: once the deadline has passed, no
        further set-up step runs (the scene stops between two objects) and the trial ends as
        'timeout'."""
        seed = check_seed(seed)
        time_budget_s = check_time_budget(time_budget_s)
        observer = observer_of(self.progress)
        episode = Episode.begin(problem, time_budget_s, observer)
        observer.started(
            self.name, problem.name, problem.horizon, episode.deadline - episode.start_time
        )
        try:
            with episode.clock.timed("setup"):
                domain = Domain(
                    problem,
                    Sim(problem.spec, stop=episode.out_of_time),
                    sampler_settings=self.settings.samplers,
                    reward_settings=self.settings.rewards,
                )
        except SceneAbandoned:
            observer.message("the deadline passed while the scene was built")
            return episode.finish(None, self.name, seed, "timeout")
        try:
            with episode.clock.timed("setup"):
                trial, decider = self._set_up(domain, episode, seed)
            termination = "timeout" if decider is None else run(trial, decider)
            return episode.finish(
                domain,
                self.name,
                seed,
                termination,
                simulations=trial.simulations,
                replans=trial.replans,
                details=None if decider is None else decider.details(),
            )
        finally:
            domain.close()

    def _set_up(self, domain: Domain, episode: Episode, seed: int) -> tuple[Trial, Decider | None]:
        """The trial and the method's decisions; no decisions when the deadline passed
        during set-up (the scene, the predicate engine): the method is then not started."""
        engine = PredicateEngine(
            episode.problem,
            domain.sim,
            domain.base_planner,
            self.settings.predicates,
            occlusion=self.occlusion,
        )
        episode.keep_predicates(engine)
        trial = Trial(
            domain,
            episode,
            np.random.default_rng(seed),
            seed,
            reuse_tree=self.settings.execution.reuse_tree,
        )
        if episode.out_of_time():
            trial.say("the deadline passed while the trial was set up")
            return trial, None
        return trial, self.start(trial)


def run(trial: Trial, decider: Decider) -> str:
    """The online loop: decide, execute, until a stop reason or a terminating decision.

    A predicate computation the trial's deadline cut short (:exc:`DeadlinePassed`, raised
    from wherever a decision needed predicates) ends the trial as 'timeout'; what was
    executed before stays the trial's plan."""
    horizon = trial.episode.problem.horizon
    try:
        while (termination := trial.episode.stop_reason(trial.domain)) is None:
            trial.episode.observer.step(trial.done, horizon)
            decision = decider.decide()
            if isinstance(decision, str):
                log.info("step %d of %d: %s", trial.done, horizon, decision)
                return decision
            log.info(
                "step %d of %d: executes %s",
                trial.done,
                horizon,
                ", ".join(str(action.discrete) for action in decision) or "nothing (asks again)",
            )
            for action in decision:
                trial.execute(action)
    except DeadlinePassed:
        trial.say("the deadline passed while predicates were computed")
        return "timeout"
    return termination
