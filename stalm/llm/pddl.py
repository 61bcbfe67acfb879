"""The prompt's abstraction as strict PDDL, for real planners, validators and tests.

The prompt (:mod:`stalm.llm.prompt`) must keep the paper's PDDL-*style* wording, which no parser
accepts: untyped parameters, comments that swallow parentheses, an effect that names variables
the action does not bind. This module writes the same domain so that a toolchain accepts it
(it is checked with Fast Downward's translator and the ``pddl`` parser in the tests), which lets
us confirm the abstraction means what the prompt claims and gives baselines a real domain.

Where strict PDDL forces a choice, the choice and its reason:

* ``place``'s reference is a region (for ``on``) or another movable (for the four relative
  directions), so it is typed by the supertype ``placeable``; an ADL precondition ties the
  direction to the reference's kind and forbids placing an object relative to itself. Its
  ground actions are then exactly :meth:`Vocabulary.all_discrete_actions`.
* ``pick`` deletes every ``AtPosition`` of the picked object with a ``forall`` effect (the
  paper's ``(not (AtPosition ?subject ?direction ?reference))`` leaves both unbound).
* Occlusions are cleared by the entity that causes them, as the paper's predicate cache does
  (Appendix A): picking an occluder, or opening an occluding door, deletes the occlusions it
  caused. Occlusions a placement would create are not predicted (the abstraction is optimistic
  there, as the prompt is); STaLM recomputes the predicates from geometry at every query.
* ``UnsafePick``/``UnsafePlace`` stay derived predicates (``:derived-predicates``), as in the
  prompt, rather than being compiled into the preconditions.
* Beyond the prompt, ``CannotPick``/``CannotPlace`` (actions no motion can do in the state,
  :data:`~stalm.predicates.literals.CANNOT_PREDICATES`) rule those actions out with the
  occlusions: a classical planner must not count on them, as the paper's prompt let it.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from stalm.domain.actions import DIRECTIONS
from stalm.domain.vocabulary import Vocabulary
from stalm.errors import StalmError
from stalm.llm.prompt import DOOR_TYPE, MOVABLE_TYPE, REGION_TYPE, PromptOptions
from stalm.predicates.literals import (
    CANNOT_PREDICATES,
    OCCLUSION_PREDICATES,
    SCOPE_PREDICATE,
    GroundLiteral,
)

DOMAIN_NAME = "shop"
#: Supertype of everything ``place`` can put an object relative to: regions and movables.
PLACEABLE_TYPE = "placeable"
DIRECTION_TYPE = "direction"
#: Every named thing of the scene (not the directions): what may occlude an action. The root
#: ``object`` would do, but the ``pddl`` parser rejects variables typed by the implicit root.
ENTITY_TYPE = "entity"

#: Number of arguments of each predicate a problem may state.
PREDICATE_ARITY: dict[str, int] = {
    "HandAvailable": 0,
    "RobotHolding": 1,
    "AtPosition": 3,
    "IsClosed": 1,
    "PickOccludedBy": 2,
    "PlaceOccludedBy": 4,
    "CannotPick": 1,
    "CannotPlace": 3,
}

#: The geometric-feedback predicates (``domain_pddl(feedback=True)``): a pick or placement
#: that failed geometrically, and whether the region concerned is as it was then apart from
#: the acting object (picking the object itself does not make room for it). Only a
#: classical planner reads them; the paper's prompt never shows them.
FEEDBACK_ARITY: dict[str, int] = {
    "PickFailed": 2,
    "PlaceFailed": 4,
    "RegionUnchangedFor": 2,
    "GoalRelation": 3,
    "Forbids": 5,
    "ForbidsPick": 3,
    "Needs": 2,
}
#: The type of the problem's failure objects: one per placement that failed beside other
#: objects, ``(Forbids f o dir ref region)`` while every ``(Needs f other)`` is on the region,
#: and one per pick that collided with objects on the region it was on, ``(ForbidsPick f o
#: region)`` while ``o`` and every ``(Needs f other)`` are on the region.
FAILURE_TYPE = "failure"
#: The feedback predicates whose first argument is a failure object.
FAILURE_PREDICATES = ("Forbids", "ForbidsPick", "Needs")

_PDDL_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]*")
_RESERVED = frozenset({"object", "either", "and", "or", "not", "forall", "exists", "when"})

_TYPES = f"""  (:types
    {ENTITY_TYPE} {DIRECTION_TYPE} - object
    {PLACEABLE_TYPE} {DOOR_TYPE} - {ENTITY_TYPE}
    {MOVABLE_TYPE} {REGION_TYPE} - {PLACEABLE_TYPE})"""

_CONSTANTS = f"  (:constants {' '.join(DIRECTIONS)} - {DIRECTION_TYPE})"

_BASE_PREDICATES = """    (HandAvailable)
    (RobotHolding ?subject - movable_object)
    (AtPosition ?subject - movable_object ?direction - direction ?reference - placeable)
    (IsClosed ?door - openable)"""

_OCCLUSION_PREDICATES = """    (PickOccludedBy ?subject - movable_object ?occluder - entity)
    (PlaceOccludedBy ?subject - movable_object ?direction - direction ?reference - placeable
                     ?occluder - entity)
    (UnsafePick ?subject - movable_object)
    (UnsafePlace ?subject - movable_object ?direction - direction ?reference - placeable)
    (CannotPick ?subject - movable_object)
    (CannotPlace ?subject - movable_object ?direction - direction ?reference - placeable)"""

_FEEDBACK_PREDICATES = """    (PickFailed ?subject - movable_object ?region - region)
    (PlaceFailed ?subject - movable_object ?direction - direction ?reference - placeable
                 ?region - region)
    (RegionUnchangedFor ?region - region ?subject - movable_object)
    (GoalRelation ?subject - movable_object ?direction - direction ?reference - placeable)
    (Forbids ?failure - failure ?subject - movable_object ?direction - direction
             ?reference - placeable ?region - region)
    (ForbidsPick ?failure - failure ?subject - movable_object ?region - region)
    (Needs ?failure - failure ?other - movable_object)"""

_DERIVED = """  (:derived (UnsafePick ?subject - movable_object)
    (exists (?occluder - entity) (PickOccludedBy ?subject ?occluder)))

  (:derived (UnsafePlace ?subject - movable_object ?direction - direction
                         ?reference - placeable)
    (exists (?occluder - entity) (PlaceOccludedBy ?subject ?direction ?reference ?occluder)))"""


def _clear_occlusions_by(entity: str) -> str:
    """Effects deleting every occlusion that ``entity`` causes (paper, Appendix A)."""
    return f"""
      (forall (?other - movable_object) (not (PickOccludedBy ?other {entity})))
      (forall (?other - movable_object ?direction - direction ?reference - placeable)
        (not (PlaceOccludedBy ?other ?direction ?reference {entity})))"""


_PICK_FEEDBACK = """
      (not (exists (?region - region)
        (and (PickFailed ?subject ?region) (RegionUnchangedFor ?region ?subject))))
      (not (exists (?failure - failure ?region - region)
        (and (ForbidsPick ?failure ?subject ?region) (AtPosition ?subject on ?region)
             (forall (?other - movable_object)
               (or (not (Needs ?failure ?other)) (AtPosition ?other on ?region))))))"""

_PLACE_FEEDBACK = """
      (not (exists (?region - region)
        (and (PlaceFailed ?subject ?direction ?reference ?region)
             (RegionUnchangedFor ?region ?subject))))
      (not (exists (?region - region)
        (and (AtPosition ?reference on ?region) (PlaceFailed ?subject on ?region ?region)
             (RegionUnchangedFor ?region ?subject))))
      (not (exists (?failure - failure ?region - region)
        (and (or (Forbids ?failure ?subject ?direction ?reference ?region)
                 (and (AtPosition ?reference on ?region)
                      (Forbids ?failure ?subject on ?region ?region)))
             (forall (?other - movable_object)
               (or (not (Needs ?failure ?other)) (AtPosition ?other on ?region))))))"""

_PICK_TOUCHES = """
      (forall (?region - region ?other - movable_object)
        (when (and (AtPosition ?subject on ?region) (not (= ?other ?subject)))
          (not (RegionUnchangedFor ?region ?other))))"""


def _actions(occlusion: bool, feedback: bool = False, goal_relations_only: bool = False) -> str:
    """The three operators. Beyond the prompt's domain, a relative PLACE also puts the object
    on its reference's region (as it does geometrically), so goals such as P2's "on table2 and
    right_of bottle1" are reachable for a classical planner. With ``feedback``, a pick or
    placement that failed geometrically is ruled out while its region is unchanged, and a
    pick marks the region it takes from as changed for every other object (taking an object
    away makes room for the others, not for itself; :mod:`stalm.proposers.feedback`). With
    ``goal_relations_only`` a relative PLACE is grounded only for the goal's own relations
    (``GoalRelation``): any
    other object is put *on* a region, which covers every spot a relative placement there
    could name, so no plan is lost while the planner's choices (and its grounding, which
    grows with objects squared) shrink to what can matter."""
    pick_safe = " (not (UnsafePick ?subject)) (not (CannotPick ?subject))" if occlusion else ""
    place_safe = (
        "\n      (not (UnsafePlace ?subject ?direction ?reference))"
        "\n      (not (CannotPlace ?subject ?direction ?reference))"
        if occlusion
        else ""
    )
    pick_safe += _PICK_FEEDBACK if feedback else ""
    place_safe += _PLACE_FEEDBACK if feedback else ""
    pick_clears = _clear_occlusions_by("?subject") if occlusion else ""
    pick_clears += _PICK_TOUCHES if feedback else ""
    relative_goal = " (GoalRelation ?subject ?direction ?reference)" if goal_relations_only else ""
    open_clears = _clear_occlusions_by("?door") if occlusion else ""
    return f"""  (:action pick
    :parameters (?subject - movable_object)
    :precondition (and (HandAvailable){pick_safe})
    :effect (and
      (not (HandAvailable))
      (RobotHolding ?subject)
      (forall (?direction - direction ?reference - placeable)
        (not (AtPosition ?subject ?direction ?reference))){pick_clears}))

  (:action place
    :parameters (?subject - movable_object ?direction - direction ?reference - placeable)
    :precondition (and
      (RobotHolding ?subject){place_safe}
      (or (and (= ?direction on)
               (exists (?region - region) (= ?region ?reference)))
          (and (not (= ?direction on))
               (not (= ?reference ?subject)){relative_goal}
               (exists (?other - movable_object) (= ?other ?reference)))))
    :effect (and
      (not (RobotHolding ?subject))
      (HandAvailable)
      (AtPosition ?subject ?direction ?reference)
      (forall (?region - region)
        (when (and (not (= ?direction on)) (AtPosition ?reference on ?region))
          (AtPosition ?subject on ?region)))))

  (:action open
    :parameters (?door - openable)
    :precondition (and (IsClosed ?door) (HandAvailable))
    :effect (and
      (not (IsClosed ?door)){open_clears}))"""


def requirements(options: PromptOptions) -> tuple[str, ...]:
    """The PDDL requirements the domain uses; derived predicates only with occlusions."""
    needed = [
        ":strips",
        ":typing",
        ":negative-preconditions",
        ":disjunctive-preconditions",
        ":equality",
        ":existential-preconditions",
        ":conditional-effects",
    ]
    if options.occlusion_predicates:
        needed.append(":derived-predicates")
    return tuple(needed)


def domain_pddl(
    options: PromptOptions = PromptOptions(),  # noqa: B008 - frozen
    *,
    feedback: bool = False,
    goal_relations_only: bool = False,
) -> str:
    """The strict PDDL domain; ``options.occlusion_predicates`` as in the prompt's ablation,
    ``feedback`` adds the geometric-feedback predicates (:data:`FEEDBACK_ARITY`) and
    ``goal_relations_only`` (with ``feedback``) keeps relative placements to the goal's."""
    occlusion = options.occlusion_predicates
    predicates = _BASE_PREDICATES + ("\n" + _OCCLUSION_PREDICATES if occlusion else "")
    predicates += "\n" + _FEEDBACK_PREDICATES if feedback else ""
    types = _TYPES.replace(" - object", f" {FAILURE_TYPE} - object") if feedback else _TYPES
    parts = [
        f"(define (domain {DOMAIN_NAME})\n  (:requirements {' '.join(requirements(options))})",
        types,
        _CONSTANTS,
        f"  (:predicates\n{predicates})",
    ]
    if occlusion:
        parts.append(_DERIVED)
    parts.append(_actions(occlusion, feedback, feedback and goal_relations_only))
    return "\n\n".join(parts) + ")\n"


def _check_names(vocabulary: Vocabulary) -> None:
    """Names must be PDDL names, distinct ignoring case, and not clash with the directions."""
    seen: dict[str, str] = {direction: direction for direction in DIRECTIONS}
    for name in vocabulary.all_names:
        if not _PDDL_NAME.fullmatch(name) or name.lower() in _RESERVED:
            raise StalmError(f"name {name!r} is not a valid PDDL name")
        previous = seen.get(name.lower())
        if previous is not None:
            raise StalmError(f"name {name!r} clashes with {previous!r} (PDDL ignores case)")
        seen[name.lower()] = name


def failure_name(index: int) -> str:
    """The PDDL object of the ``index``-th failure of a feedback problem."""
    return f"failure{index}"


def _check_literal(
    vocabulary: Vocabulary, literal: GroundLiteral, field: str, feedback: bool = False
) -> None:
    arity = PREDICATE_ARITY.get(literal.name)
    if arity is None and feedback:
        arity = FEEDBACK_ARITY.get(literal.name)
    if arity is None:
        raise StalmError(f"{field}: unknown predicate {literal.name!r} in {literal}")
    if len(literal.args) != arity:
        raise StalmError(
            f"{field}: {literal.name} takes {arity} argument(s), got {len(literal.args)} "
            f"in {literal}"
        )
    known = set(vocabulary.all_names) | set(DIRECTIONS)
    if feedback and literal.name in FAILURE_PREDICATES:
        known.add(literal.args[0])
    for arg in literal.args:
        if arg not in known:
            raise StalmError(f"{field}: unknown name {arg!r} in {literal}")


def _atom(literal: GroundLiteral) -> str:
    return "(" + " ".join((literal.name, *literal.args)) + ")"


def problem_pddl(
    vocabulary: Vocabulary,
    init: Sequence[GroundLiteral],
    goal: Sequence[GroundLiteral],
    name: str,
    options: PromptOptions = PromptOptions(),  # noqa: B008 - frozen
    *,
    feedback: bool = False,
    failures: int = 0,
) -> str:
    """A strict PDDL problem for :func:`domain_pddl` with the same options.

    With ``feedback`` the init may hold the feedback predicates (``failures`` failure objects
    ``failure0`` ... are declared for ``Forbids``/``ForbidsPick``/``Needs``), every region starts
    ``RegionUnchangedFor`` every movable object, and the goal's relative ``AtPosition``
    atoms become ``GoalRelation`` facts.

    ``name`` becomes the problem's PDDL name (characters PDDL does not allow become ``-``).
    Raises :class:`StalmError` for names PDDL cannot express and for literals with unknown
    predicates, wrong arity or unknown names.
    """
    _check_names(vocabulary)
    init = [literal for literal in init if literal.name != SCOPE_PREDICATE]  # no PDDL fact
    for literal in init:
        _check_literal(vocabulary, literal, "init", feedback)
        if literal.name in FAILURE_PREDICATES and literal.args[0] not in {
            failure_name(i) for i in range(failures)
        }:
            raise StalmError(f"init: {literal} names an undeclared failure object")
    for literal in goal:
        _check_literal(vocabulary, literal, "goal")
    if not options.occlusion_predicates:
        hidden = OCCLUSION_PREDICATES | CANNOT_PREDICATES
        init = [literal for literal in init if literal.name not in hidden]
    problem_name = re.sub(r"[^A-Za-z0-9_-]", "-", name)
    if not problem_name or not problem_name[0].isalpha():
        problem_name = "problem-" + problem_name
    groups = [
        (vocabulary.movables, MOVABLE_TYPE),
        (vocabulary.doors, DOOR_TYPE),
        (vocabulary.regions, REGION_TYPE),
    ]
    if feedback and failures:
        groups.append((tuple(failure_name(i) for i in range(failures)), FAILURE_TYPE))
    objects = "".join(f"\n    {' '.join(names)} - {kind}" for names, kind in groups if names)
    if feedback:
        unchanged = [
            GroundLiteral("RegionUnchangedFor", (r, o))
            for r in vocabulary.regions
            for o in vocabulary.movables
        ]
        relations = [
            GroundLiteral("GoalRelation", literal.args)
            for literal in goal
            if literal.name == "AtPosition" and literal.args[1] != "on"
        ]
        init = [*init, *unchanged, *relations]
    init_lines = "".join(f"\n    {_atom(literal)}" for literal in init)
    goal_lines = "".join(f"\n    {_atom(literal)}" for literal in goal)
    return (
        f"(define (problem {problem_name})\n"
        f"  (:domain {DOMAIN_NAME})\n"
        f"  (:objects{objects})\n"
        f"  (:init{init_lines})\n"
        f"  (:goal (and{goal_lines})))\n"
    )
