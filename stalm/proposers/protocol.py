"""What every task-plan proposer takes and gives: a :class:`ProposalRequest` in, a
:class:`Proposal` out.

The request carries everything a query can depend on (the problem, the state and its
predicate literals, how many plans, the query's seed, the deadline and the geometric feedback
that holds in the state), so a proposer has one method of one argument, and a new field
reaches every proposer without a new parameter in each. Whether a proposer can use feedback
is a property it states (:attr:`TaskPlanProposer.takes_feedback`), not something read off its
signature.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from stalm.domain.actions import DiscreteAction
from stalm.errors import StalmError
from stalm.predicates.literals import GroundLiteral
from stalm.proposers.feedback import FailedStep
from stalm.world.problem import Problem
from stalm.world.state import State


@dataclass(frozen=True)
class ProposalRequest:
    """One query for task plans: up to ``n`` plans from ``state``, whose predicates are
    ``literals`` (a set: a proposer orders them itself where order matters); stop early at
    ``deadline`` (``time.monotonic()`` seconds, None: no deadline).

    ``seed`` is the query's own (STaLM derives one per query from the trial's seed), so the
    same query asks the same thing of a model or a planner. ``feedback`` is the failed steps
    that hold in ``state`` (:class:`stalm.proposers.feedback.FailedStep`); STaLM fills it only
    when feedback is switched on, which it allows only for a proposer that
    :attr:`~TaskPlanProposer.takes_feedback`.
    """

    problem: Problem
    state: State
    literals: frozenset[GroundLiteral]
    n: int
    seed: int
    deadline: float | None = None
    feedback: tuple[FailedStep, ...] = ()


@dataclass(frozen=True)
class Proposal:
    """A batch of task plans, the replies they came from, and what asking cost.

    ``truncated[i]`` says plan ``i`` is only the beginning of its reply's plan: the reply was
    cut off inside the plan list (by ``max_tokens``) and its complete steps were kept, as the
    authors' parser did. It is aligned with ``plans``, or empty from a proposer whose plans are
    never cut (the symbolic one).

    ``seconds`` is the wall time the query took now. ``from_cache`` is true when every reply
    came from the reply cache; ``cached_seconds`` is what the calls that first produced the
    cached replies took (the cache stores it), so :attr:`original_seconds` is the time of the
    run a replay reproduces, whatever happened to be cached when it ran.
    """

    plans: tuple[tuple[DiscreteAction, ...], ...]
    unparseable: tuple[str, ...] = ()
    """Per model reply that could not be read: the parser's reason."""
    no_plan: tuple[str, ...] = ()
    """Why a planning proposer (no model: the symbolic one) found no plan; Figure 5 counts it
    as ``no_plan``, not as an unreadable reply."""
    replies: tuple[str, ...] = ()
    calls: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    seconds: float = 0.0
    from_cache: bool = False
    truncated: tuple[bool, ...] = ()
    cached_seconds: float = 0.0
    injected: tuple[str, ...] = ()
    """Per plan, what a degraded proposer did to it on purpose (:mod:`stalm.proposers.noisy`:
    ``clean``, ``inapplicable`` or the Figure 5 kind it injected); empty from every other
    proposer."""
    set_aside: tuple[str, ...] = ()
    """The predicate literals the plans were made without, as text: the symbolic proposer's
    occlusion cycles (:mod:`stalm.proposers.occlusion_cycles`) when the abstraction had no
    plan with them; empty from every other proposer."""

    @property
    def truncated_plans(self) -> int:
        """How many of ``plans`` are the kept beginning of a reply cut off inside its plan."""
        return sum(self.truncated)

    @property
    def original_seconds(self) -> float:
        """The seconds this query took when its replies were made: the stored seconds of cached
        replies plus, for replies made now, the time taken now (all of it when nothing came
        from the cache; only the stored seconds when everything did)."""
        return self.cached_seconds + (0.0 if self.from_cache else self.seconds)


class TaskPlanProposer(Protocol):
    """Anything that proposes task plans: a ``name`` for results, whether it uses geometric
    feedback, and :meth:`propose`."""

    @property
    def name(self) -> str: ...

    @property
    def takes_feedback(self) -> bool:
        """Whether :meth:`propose` reads ``request.feedback`` (STaLM refuses to run with
        feedback switched on for a proposer that would ignore it)."""
        ...

    def propose(self, request: ProposalRequest) -> Proposal:
        """Up to ``request.n`` task plans from ``request.state``."""
        ...


def check_proposer(proposer: object) -> None:
    """A StalmError naming what ``proposer`` lacks of :class:`TaskPlanProposer`: a proposer
    written for an older stalm (``propose(problem, state, literals, n, seed, ...)``, feedback
    found from its signature) would otherwise fail with a traceback at its first query."""
    missing = [part for part in ("name", "takes_feedback") if not hasattr(proposer, part)]
    if not callable(getattr(proposer, "propose", None)):
        missing.append("propose(request)")
    if missing:
        raise StalmError(
            f"{type(proposer).__name__} is no task-plan proposer: it has no "
            f"{', no '.join(missing)} (a proposer has a name, a takes_feedback flag and "
            "propose(request) taking a ProposalRequest)"
        )
