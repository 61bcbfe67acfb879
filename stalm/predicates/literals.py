"""Grounded predicates (literals) as plain immutable values.

A literal is a predicate name with its arguments, e.g. ``AtPosition(coke, on, counter2)``.
The prompt prints literals as the paper's Python-style tuples, and the PDDL writer prints them
as s-expressions; both read the same value.
"""

from __future__ import annotations

from dataclasses import dataclass

PREDICATE_NAMES: tuple[str, ...] = (
    "HandAvailable",
    "RobotHolding",
    "AtPosition",
    "IsClosed",
    "PickOccludedBy",
    "PlaceOccludedBy",
)
OCCLUSION_PREDICATES: frozenset[str] = frozenset({"PickOccludedBy", "PlaceOccludedBy"})
CANNOT_PREDICATES: frozenset[str] = frozenset({"CannotPick", "CannotPlace"})
"""Beyond the paper's predicates: CannotPick(o), CannotPlace(o, dir, ref), actions no sampled
motion can do in the state whatever is moved. They are literals of the state like the others;
the paper's prompt (Figure 13) leaves them out and a prompt setting adds them as one line
(:class:`~stalm.llm.prompt.PromptOptions`), the symbolic proposer's PDDL rules the actions out."""

SCOPE_PREDICATE = "OcclusionComputed"
"""Beyond the paper: OcclusionComputed(o) says the occlusion literals were computed for o. Only
relevance-limited predicates (``predicates.relevant_only``) state it, one per object they
covered; an object without it may be occluded or not, nobody looked. The prompt shows the
list as a section of its own; no PDDL reads it."""


@dataclass(frozen=True, order=True)
class GroundLiteral:
    """A predicate applied to object names; hashable so sets of literals describe a state."""

    name: str
    args: tuple[str, ...] = ()

    def as_tuple(self) -> tuple[str, ...]:
        """The paper's prompt form: ``('AtPosition', 'coke', 'on', 'counter2')``.

        Nullary predicates print as ``('HandAvailable', '')`` exactly as in Figure 13.
        """
        return (self.name, *self.args) if self.args else (self.name, "")

    def __str__(self) -> str:
        return f"{self.name}({', '.join(self.args)})"
