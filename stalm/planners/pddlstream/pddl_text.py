"""The PDDL that Fast Downward searches: the strict abstraction with continuous values as objects.

The domain is :mod:`stalm.llm.pddl`'s PICK / PLACE / OPEN with their continuous parameters made
explicit, as PDDLStream writes TAMP domains: ``pick(o, p, g, m)`` needs ``(PickKin o p g m)``,
a fact only a stream can certify, and so on. Occlusion is not a symbol here but geometry:
a motion is unsafe (a derived predicate) when an object currently rests at a pose its swept
volume collides with (``Collides``, certified by testing the motion against that pose) or when
it passes a closed door (``Crosses``). Goal atoms become the derived ``OnRegion`` and ``RelTo``,
true when the objects' current poses are supported by the region / stand in that direction.

Actions cost ``MotionCost`` of their motion: 1 for a real motion, more for an optimistic one
(PDDLStream's stream effort), so a plan over values already computed is preferred.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence

from stalm.domain.actions import RELATIVE_DIRECTIONS
from stalm.errors import StalmError

DOMAIN_NAME = "pddlstream-shop"

Fact = tuple[str, ...]
"""A ground atom: predicate name then arguments."""

#: PDDL type of each kind of object.
TYPES = ("movable", "region", "door", "pose", "grasp", "motion")

DOMAIN_PDDL = f"""(define (domain {DOMAIN_NAME})
  (:requirements :strips :typing :negative-preconditions :disjunctive-preconditions
                 :existential-preconditions :derived-predicates :action-costs)
  (:types {" ".join(TYPES)} direction - object)
  (:constants {" ".join(RELATIVE_DIRECTIONS)} - direction)
  (:predicates
    (AtPose ?o - movable ?p - pose)
    (Holding ?o - movable ?g - grasp)
    (HandEmpty)
    (IsClosed ?d - door)
    (Supported ?o - movable ?p - pose ?r - region)
    (Rel ?o - movable ?p - pose ?dir - direction ?o2 - movable ?p2 - pose)
    (PickKin ?o - movable ?p - pose ?g - grasp ?m - motion)
    (PlaceKin ?o - movable ?p - pose ?g - grasp ?m - motion)
    (OpenKin ?d - door ?m - motion)
    (Collides ?m - motion ?o - movable ?p - pose)
    (Crosses ?m - motion ?d - door)
    (UnsafeMotion ?m - motion)
    (OnRegion ?o - movable ?r - region)
    (RelTo ?o - movable ?dir - direction ?o2 - movable))
  (:functions (total-cost) - number (MotionCost ?m - motion) - number)

  (:derived (UnsafeMotion ?m - motion)
    (or (exists (?o - movable ?p - pose) (and (Collides ?m ?o ?p) (AtPose ?o ?p)))
        (exists (?d - door) (and (Crosses ?m ?d) (IsClosed ?d)))))

  (:derived (OnRegion ?o - movable ?r - region)
    (exists (?p - pose) (and (AtPose ?o ?p) (Supported ?o ?p ?r))))

  (:derived (RelTo ?o - movable ?dir - direction ?o2 - movable)
    (exists (?p - pose ?p2 - pose) (and (AtPose ?o ?p) (AtPose ?o2 ?p2) (Rel ?o ?p ?dir ?o2 ?p2))))

  (:action pick
    :parameters (?o - movable ?p - pose ?g - grasp ?m - motion)
    :precondition (and (PickKin ?o ?p ?g ?m) (AtPose ?o ?p) (HandEmpty) (not (UnsafeMotion ?m)))
    :effect (and (not (AtPose ?o ?p)) (not (HandEmpty)) (Holding ?o ?g)
                 (increase (total-cost) (MotionCost ?m))))

  (:action place
    :parameters (?o - movable ?p - pose ?g - grasp ?m - motion)
    :precondition (and (PlaceKin ?o ?p ?g ?m) (Holding ?o ?g) (not (UnsafeMotion ?m)))
    :effect (and (AtPose ?o ?p) (HandEmpty) (not (Holding ?o ?g))
                 (increase (total-cost) (MotionCost ?m))))

  (:action open
    :parameters (?d - door ?m - motion)
    :precondition (and (OpenKin ?d ?m) (IsClosed ?d) (HandEmpty) (not (UnsafeMotion ?m)))
    :effect (and (not (IsClosed ?d)) (increase (total-cost) (MotionCost ?m)))))
"""

_PDDL_NAME = re.compile(r"[a-z][a-z0-9_-]*")


def goal_fact(obj: str, direction: str, ref: str) -> Fact:
    """The derived atom standing for the goal conjunct AtPosition(obj, direction, ref)."""
    if direction == "on":
        return ("OnRegion", obj, ref)
    return ("RelTo", obj, direction, ref)


def _atom(fact: Fact) -> str:
    return "(" + " ".join(fact) + ")"


def problem_pddl(
    objects: Mapping[str, Sequence[str]],
    init: Iterable[Fact],
    costs: Mapping[str, int],
    goal: Iterable[Fact],
    name: str = "state",
) -> str:
    """A problem for :data:`DOMAIN_PDDL`: ``objects`` by PDDL type, static and fluent facts,
    the cost of every motion object, and the goal atoms.

    Raises :class:`StalmError` for an object name Fast Downward would not give back verbatim
    (plans come back in lower case) or a motion without a cost.
    """
    lines = []
    for kind in TYPES:
        names = objects.get(kind, ())
        for obj in names:
            if not _PDDL_NAME.fullmatch(obj) or obj in RELATIVE_DIRECTIONS:
                raise StalmError(f"'{obj}' cannot be a PDDL object of this planner")
        if names:
            lines.append(f"    {' '.join(names)} - {kind}")
    missing = [m for m in objects.get("motion", ()) if m not in costs]
    if missing:
        raise StalmError(f"motions without a cost: {', '.join(missing[:5])}")
    init_lines = [f"    {_atom(fact)}" for fact in init]
    init_lines += [f"    (= (MotionCost {m}) {costs[m]})" for m in objects.get("motion", ())]
    init_lines.append("    (= (total-cost) 0)")
    goal_lines = [f"    {_atom(fact)}" for fact in goal]
    return (
        f"(define (problem {name})\n"
        f"  (:domain {DOMAIN_NAME})\n"
        "  (:objects\n" + "\n".join(lines) + ")\n"
        "  (:init\n" + "\n".join(init_lines) + ")\n"
        "  (:goal (and\n" + "\n".join(goal_lines) + "))\n"
        "  (:metric minimize (total-cost)))\n"
    )
