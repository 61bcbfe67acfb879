"""What one real step of STaLM did, as plain JSON for the result file (``details["step_log"]``).

A solve's table and GIF show what was executed; this record says why. Per real step: every
task plan the proposer offered in each round, how far Concretize got with it, the paper's
Figure 5 kind of its failure and the transition's own reason (the :class:`Infeasibility` kind,
its sentence and the bodies in the way); the search tree's root actions with N and Q after
the step's search, marking the nodes the warm start put there; and the rule that chose what
was executed. ``stalm view`` draws these records; they are data, so a script can read them too.

The functions here only read the planner's objects (Concretize's plans, the tree): the
planner decides when to call them, and fills its :class:`StepRecord` with what they return.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

from stalm.domain.params import Action
from stalm.json_object import JsonObject, record_json
from stalm.predicates.literals import GroundLiteral
from stalm.search.concretize import ConcretePlan
from stalm.search.failure_kinds import figure5_kind
from stalm.search.tree import ContinuousNodeView, SearchTree
from stalm.world.state import State

TREE_CHILDREN_SHOWN = 8
"""Second-level actions kept per root action (the most visited ones): the record stays small
while still showing where each root action's simulations went next."""

DECISIONS: dict[str, str] = {
    "concretize_goal": "a proposed task plan reached the goal in Concretize: executed whole",
    "tree_goal": "a simulation of the warm-started tree reached the goal: its plan executed",
    "best_q": "no goal plan: the root action with the highest Q executed (the authors' rule)",
    "progress": "no goal plan: the highest-Q root action from which the tree knows a way to "
    "goal progress executed",
    "best_q_fallback": "no goal plan and no root action known to lead to goal progress after "
    "search_rounds searches (or at the deadline): the highest-Q root action executed",
    "best_prefix": "STaLM w/o UCT: the first action of the task plan that got furthest",
    "nothing": "no root action had a feasible sample: nothing executed, asked again",
    "timeout": "the time budget ran out during the step",
}
"""Why a step executed what it executed, by the ``decision`` a step record holds."""


Discrete = tuple[str, ...]
"""A discrete action as in result files: the operator, then its arguments."""

STEP_PARTS_NOT_REACHED = frozenset({"decision", "searches", "rules_refuted_by_tree", "executed"})
"""The fields of a step's record left out of its JSON while None (the step did not get there)."""


@dataclass(frozen=True)
class FailureReason:
    """Why Concretize stopped a task plan: the transition's :class:`Infeasibility`."""

    kind: str
    detail: str
    blockers: tuple[str, ...]


@dataclass(frozen=True)
class TaskPlanRecord:
    """One task plan and what Concretize did with it (:func:`task_plan_record`)."""

    index: int
    actions: tuple[Discrete, ...]
    unparseable: str | None
    no_plan: str | None
    reached_goal: bool
    kind: str | None
    """The Figure 5 kind of its failure, as the experiment counts it."""
    concretize_kind: str | None
    """The transition's own kind of failure."""
    failed_step: int | None
    feasible_steps: int
    """How many of its steps got a feasible κ."""
    truncated: bool
    detail: str | None
    reason: FailureReason | None

    def to_json(self) -> JsonObject:
        return record_json(self)


@dataclass(frozen=True)
class RoundLessons:
    """What a feedback round taught: its failure kinds, the lessons not known before (a rule
    adds no PDDL fact) and the rules its grounded steps refuted."""

    failures: tuple[str, ...]
    facts_learned: int
    rules_refuted: int


@dataclass(frozen=True)
class ProposalRound:
    """One proposal round of a step: the facts the proposer was told, the plans it gave, the
    literals it planned without (the symbolic proposer's occlusion cycles) and, with
    feedback, what the round taught."""

    round: int
    feedback_facts: int
    plans: tuple[TaskPlanRecord, ...]
    set_aside: tuple[str, ...] = ()
    lessons: RoundLessons | None = None

    def to_json(self) -> JsonObject:
        """The fields as JSON, ``set_aside`` only when there is any, the lessons' at the end."""
        entry = record_json(self, omitted_when_none={"lessons"})
        if not self.set_aside:
            del entry["set_aside"]
        lessons: JsonObject = entry.pop("lessons", {})
        return entry | lessons


@dataclass(frozen=True)
class TreeActionRecord:
    """A continuous node of the tree: its action, N, Q (to 4 places), κ children, feasible
    ones, whether the warm start put it there; a root action also lists the most visited
    actions below it (``children``; None below the root)."""

    action: Discrete
    n: int
    q: float
    kappas: int
    feasible_kappas: int
    warm: bool
    children: tuple[TreeActionRecord, ...] | None = None

    def to_json(self) -> JsonObject:
        return record_json(self, omitted_when_none={"children"})


@dataclass(frozen=True)
class TreeRecord:
    """The tree after a step's search (:func:`tree_record`)."""

    root_visits: int
    root_visits_before: int
    discrete_nodes: int
    kappa_children: int
    root_actions: int
    untried_root_actions: int
    actions: tuple[TreeActionRecord, ...]

    def to_json(self) -> JsonObject:
        return record_json(self)


@dataclass
class StepRecord:
    """One real step's entry of the log, filled in as the step runs: the step that begins it
    makes it and hands it to each part of the step that has something to say (the proposals,
    the search and its decision), so no part writes into another's state. Only the step that
    owns it changes it; :meth:`to_json` is what the result file keeps."""

    step: int
    """Real steps executed before this one."""
    proposals: list[ProposalRound] = field(default_factory=list)
    """Per proposal round: :func:`proposal_record`, with what a feedback round taught."""
    tree: TreeRecord | None = None
    """The search tree after the step's search (:func:`tree_record`); None without one."""
    decision: str | None = None
    """Why the step executed what it did: a key of :data:`DECISIONS`."""
    searches: int | None = None
    """Searches run from this root (the 'progress' rule may run several)."""
    rules_refuted_by_tree: int | None = None
    """Feedback rules refuted by what the tree's simulations grounded."""
    executed: int | None = None
    """Actions executed at the end of the step."""

    def executes(
        self, actions: tuple[Action, ...], decision: str | None = None
    ) -> tuple[Action, ...]:
        """The step ends executing ``actions``; ``decision``: why, unless already said."""
        if decision is not None:
            self.decision = decision
        self.executed = len(actions)
        return actions

    def timed_out(self) -> str:
        """The step ends the trial: its deadline passed."""
        self.decision = "timeout"
        return "timeout"

    def learned(self, lessons: RoundLessons) -> None:
        """The last proposal round taught ``lessons`` (geometric feedback)."""
        self.proposals[-1] = replace(self.proposals[-1], lessons=lessons)

    def to_json(self) -> JsonObject:
        """The entry as plain JSON; what a step did not reach is left out (``tree`` is kept
        as null)."""
        return record_json(self, omitted_when_none=STEP_PARTS_NOT_REACHED)


def action_json(action: object) -> Discrete:
    """A discrete action as in result files (``("place", "salter", "right_of", "bottle1")``)."""
    as_tuple = getattr(action, "as_tuple", None)
    return tuple(as_tuple()) if callable(as_tuple) else (str(action),)


def _reason(plan: ConcretePlan) -> FailureReason | None:
    """The failed step's Infeasibility: kind, sentence and blockers (None if no step failed)."""
    if plan.failed_step is None or plan.failed_step >= len(plan.steps):
        return None
    why = plan.steps[plan.failed_step].infeasibility
    if why is None:
        return None
    return FailureReason(why.kind, why.detail, tuple(why.blockers))


def task_plan_record(plan: ConcretePlan, root_literals: Iterable[GroundLiteral]) -> TaskPlanRecord:
    """One task plan and what Concretize did with it; ``root_literals`` (the prompt's
    predicates) judge whether its first step was occluded (its Figure 5 ``kind``)."""
    return TaskPlanRecord(
        index=plan.index,
        actions=tuple(action_json(action) for action in plan.task_plan.actions),
        unparseable=plan.task_plan.unparseable,
        no_plan=plan.task_plan.no_plan,
        reached_goal=plan.reached_goal,
        kind=figure5_kind(plan, root_literals),
        concretize_kind=plan.failure,
        failed_step=plan.failed_step,
        feasible_steps=len(plan.actions),
        truncated=plan.truncated,
        detail=plan.detail,
        reason=_reason(plan),
    )


def proposal_record(
    round_: int,
    feedback_facts: int,
    plans: Sequence[ConcretePlan],
    root_literals: Iterable[GroundLiteral],
    set_aside: Sequence[str] = (),
) -> ProposalRound:
    """One proposal round of a step: the facts the proposer was told and the plans it gave."""
    literals = frozenset(root_literals)
    records = tuple(task_plan_record(plan, literals) for plan in plans)
    return ProposalRound(round_, feedback_facts, records, tuple(set_aside))


def warm_edges(plans: Iterable[ConcretePlan]) -> frozenset[tuple[State, object]]:
    """(state, discrete action) of every step the warm start put into the tree."""
    return frozenset((step.state, step.action) for plan in plans for step in plan.steps)


def _action_node(
    cont: ContinuousNodeView,
    state: State,
    warm: frozenset[tuple[State, object]],
    children: tuple[TreeActionRecord, ...] | None = None,
) -> TreeActionRecord:
    return TreeActionRecord(
        action=action_json(cont.action),
        n=cont.n,
        q=round(cont.q, 4),
        kappas=len(cont.children),
        feasible_kappas=sum(child.outcome.feasible for child in cont.children),
        warm=(state, cont.action) in warm,
        children=children,
    )


def tree_record(
    tree: SearchTree, warm: frozenset[tuple[State, object]], visits_before: int = 0
) -> TreeRecord:
    """The tree after a step's search: every root action that was visited or warm-started
    (with N, Q, κ counts and whether the warm start put it there), and below each the most
    visited actions from the state its most visited feasible κ leads to. Root actions never
    tried are only counted. ``visits_before`` is the root's N before the step (tree reuse)."""
    root = tree.node(tree.root)
    shown: list[TreeActionRecord] = []
    for cont in sorted(root.children, key=lambda c: (-c.n, -c.q)):
        if cont.n == 0 and (tree.root, cont.action) not in warm:
            continue
        feasible = [k for k in cont.children if k.outcome.feasible and k.n > 0]
        children: tuple[TreeActionRecord, ...] = ()
        if feasible:
            best = max(feasible, key=lambda k: (k.n, k.q))
            following = best.outcome.state
            if following in tree:
                below = [c for c in tree.node(following).children if c.n > 0]
                below.sort(key=lambda c: (-c.n, -c.q))
                children = tuple(
                    _action_node(c, following, warm) for c in below[:TREE_CHILDREN_SHOWN]
                )
        shown.append(_action_node(cont, tree.root, warm, children))
    stats = tree.stats()
    return TreeRecord(
        root_visits=root.n,
        root_visits_before=visits_before,
        discrete_nodes=stats.discrete_nodes,
        kappa_children=stats.kappa_children,
        root_actions=len(root.children),
        untried_root_actions=len(root.children) - len(shown),
        actions=tuple(shown),
    )
