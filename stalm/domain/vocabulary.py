"""The names a problem gives to its entities: what an action or a literal may mention.

Prompts, PDDL, reply parsing and output constraints all need the same three name lists and
nothing else of the scene, so they take a :class:`Vocabulary` rather than a whole problem.
"""

from __future__ import annotations

from dataclasses import dataclass

from stalm.domain.actions import DIRECTIONS, RELATIVE_DIRECTIONS, DiscreteAction, Open, Pick, Place
from stalm.world.problem import Problem


@dataclass(frozen=True)
class Vocabulary:
    """Entity names of one problem, in the problem file's order."""

    movables: tuple[str, ...]
    regions: tuple[str, ...]
    doors: tuple[str, ...]

    @staticmethod
    def from_problem(problem: Problem) -> Vocabulary:
        """The names of a loaded problem, in its file's order."""
        spec = problem.spec
        return Vocabulary(
            movables=tuple(o.name for o in spec.objects),
            regions=tuple(r.name for r in spec.regions),
            doors=tuple(d.name for d in spec.doors),
        )

    @property
    def all_names(self) -> tuple[str, ...]:
        return self.movables + self.regions + self.doors

    def kind_of(self, name: str) -> str | None:
        """``'movable'``, ``'region'``, ``'door'`` or None for a name the problem lacks."""
        if name in self.movables:
            return "movable"
        if name in self.regions:
            return "region"
        if name in self.doors:
            return "door"
        return None

    def all_discrete_actions(self) -> tuple[DiscreteAction, ...]:
        """Every grounded action, regardless of state: the discrete action space A(δ).

        PLACE(o, on, r) for every region r and PLACE(o, dir, o') for the four relative
        directions and every other movable o' (doors are not regions), as the authors did.
        """
        actions: list[DiscreteAction] = [Pick(o) for o in self.movables]
        for obj in self.movables:
            actions.extend(Place(obj, "on", region) for region in self.regions)
            for ref in self.movables:
                if ref != obj:
                    actions.extend(Place(obj, d, ref) for d in RELATIVE_DIRECTIONS)
        actions.extend(Open(door) for door in self.doors)
        return tuple(actions)

    @property
    def directions(self) -> tuple[str, ...]:
        return DIRECTIONS
