"""The movable objects a symbolic task needs: leave out those no action on which can matter.

At 64 objects, Fast Downward's translator took most of a relevance-limited trial (a median
4.1 s of 5.6; 7.4 s for scale_061's first query on a shared core) grounding PICK and PLACE,
their forall effects and the feedback facts for every object, while the plan it found moved 9.
An object the abstraction says nothing about but where it stands is such an object: no
action on it can make a precondition or the goal true, so leaving it out of the task loses
no plan (scale_061's translation: 7.35 s -> 0.24 s, a plan of the same length).

An object is kept when
- the goal names it;
- a literal other than a position names it (an occlusion, as occluder or occluded, what the
  robot holds, a feedback fact: ``Needs`` names the objects a failed placement's rule waits
  for);
- it stands on a region a feedback fact names: picking it would change that region, and a
  changed region lifts the failed pick or placement recorded there (``RegionUnchangedFor``),
  which is how a plan makes room on a crowded region.
Every other object only stands somewhere: picking it clears no occlusion (it causes none),
changes no region whose change is read, and placing it makes nothing true that a
precondition or the goal reads. Literals naming a left-out object are left out with it.

This holds where relative placements are grounded only for the goal's relations (the
proposer's ``goal_relations_only``, on by default), whose references the goal names; the
proposer prunes only then. The language model's prompt is not touched: it lists every
object, as the paper's does.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import replace

from stalm.domain.vocabulary import Vocabulary
from stalm.predicates.literals import GroundLiteral

POSITION = "AtPosition"
REGION_NAMING_FEEDBACK = {"PickFailed": 1, "PlaceFailed": 3, "Forbids": 4, "ForbidsPick": 2}
"""The feedback facts that name a region whose change lifts them, and that region's index."""


def task_objects(
    vocabulary: Vocabulary, init: Iterable[GroundLiteral], goal: Sequence[GroundLiteral]
) -> tuple[Vocabulary, list[GroundLiteral]]:
    """The vocabulary with only the movable objects the task needs (see the module), and the
    init literals that name no other movable object."""
    init = list(init)
    movables = set(vocabulary.movables)
    needed = {name for literal in goal for name in literal.args if name in movables}
    for literal in init:
        if literal.name != POSITION:
            needed |= {name for name in literal.args if name in movables}
    watched_regions = {
        literal.args[REGION_NAMING_FEEDBACK[literal.name]]
        for literal in init
        if literal.name in REGION_NAMING_FEEDBACK  # a wrong arity is problem_pddl's error
        and len(literal.args) > REGION_NAMING_FEEDBACK[literal.name]
    }
    needed |= {
        literal.args[0]
        for literal in init
        if literal.name == POSITION
        and literal.args[1] == "on"
        and literal.args[2] in watched_regions
    }
    kept = replace(vocabulary, movables=tuple(m for m in vocabulary.movables if m in needed))
    literals = [
        literal
        for literal in init
        if all(name in needed or name not in movables for name in literal.args)
    ]
    return kept, literals
