"""Vocabularies of the paper's problems and the Figure 13 state, as test data.

Names come from /work/shared/research/scenarios.md (the authors' scenario facts) and, for the
Figure 13 prompt, from the prompt itself, which lists a ``pork_grill`` that the P5 roster in
the scenario facts lacks. Every problem has the kitchen door of the shared layout.
"""

from __future__ import annotations

from stalm.domain.vocabulary import Vocabulary
from stalm.predicates.literals import GroundLiteral

KITCHEN_DOOR = ("kitchen_door",)
SEVEN_REGIONS = (
    "sink_counter_left",
    "minifridge",
    "counter1",
    "counter2",
    "shelf_lower",
    "table1",
    "table2",
)

P1 = Vocabulary(
    movables=("salter1", "salter2", "bottle2", "bottle1", "bottle3", "salter3"),
    regions=SEVEN_REGIONS,
    doors=KITCHEN_DOOR,
)
P2 = Vocabulary(
    movables=("salter", "bottle2", "bottle3", "bottle1"), regions=SEVEN_REGIONS, doors=KITCHEN_DOOR
)
P3 = Vocabulary(
    movables=(
        "beer",
        "milk",
        "coke",
        "sprite",
        "fanta",
        "water",
        "wine",
        "orange_juice",
        "grape_juice",
        "cocoa",
        "whiskey",
        "welchies",
    ),
    regions=("counter2", "table1"),
    doors=KITCHEN_DOOR,
)
P4 = Vocabulary(
    movables=("salter", "bottle2", "bottle3", "bottle1", "plate"),
    regions=SEVEN_REGIONS,
    doors=KITCHEN_DOOR,
)
P5 = Vocabulary(
    movables=("coke", "beef_grill", "sprite", "mango_juice", "dr_pepper"),
    regions=("counter1", "counter2", "counter3", "counter5"),
    doors=KITCHEN_DOOR,
)
P6 = Vocabulary(
    movables=("coke", "beef_grill", "wine", "beer", "sprite"),
    regions=SEVEN_REGIONS,
    doors=KITCHEN_DOOR,
)

#: The objects of the Figure 13 prompt, in its order (movables, then the door, then regions).
FIGURE13_VOCABULARY = Vocabulary(
    movables=("coke", "sprite", "mango_juice", "dr_pepper", "pork_grill", "beef_grill"),
    regions=("counter1", "counter2", "counter3", "counter5"),
    doors=KITCHEN_DOOR,
)

FIGURE13_GOAL = (
    GroundLiteral("AtPosition", ("coke", "on", "counter1")),
    GroundLiteral("AtPosition", ("sprite", "on", "counter1")),
    GroundLiteral("AtPosition", ("beef_grill", "on", "counter1")),
)


def _lit(name: str, *args: str) -> GroundLiteral:
    return GroundLiteral(name, args)


#: The init of Figure 13, in its order (transcribed from the paper).
FIGURE13_INIT = (
    _lit("HandAvailable"),
    _lit("AtPosition", "coke", "on", "counter2"),
    _lit("AtPosition", "beef_grill", "on", "counter2"),
    _lit("AtPosition", "coke", "behind_of", "beef_grill"),
    _lit("AtPosition", "beef_grill", "front_of", "coke"),
    _lit("AtPosition", "sprite", "on", "counter3"),
    _lit("AtPosition", "mango_juice", "on", "counter5"),
    _lit("AtPosition", "dr_pepper", "on", "counter5"),
    _lit("AtPosition", "mango_juice", "behind_of", "dr_pepper"),
    _lit("AtPosition", "dr_pepper", "front_of", "mango_juice"),
    _lit("PickOccludedBy", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "beef_grill", "left_of", "coke", "coke"),
    _lit("PlaceOccludedBy", "beef_grill", "left_of", "sprite", "sprite"),
    _lit("PlaceOccludedBy", "beef_grill", "right_of", "mango_juice", "dr_pepper"),
    _lit("PlaceOccludedBy", "beef_grill", "right_of", "mango_juice", "mango_juice"),
    _lit("PlaceOccludedBy", "beef_grill", "left_of", "dr_pepper", "dr_pepper"),
    _lit("PlaceOccludedBy", "sprite", "on", "counter2", "beef_grill"),
    _lit("PlaceOccludedBy", "sprite", "left_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "sprite", "right_of", "coke", "coke"),
    _lit("PlaceOccludedBy", "sprite", "right_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "sprite", "behind_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "sprite", "behind_of", "beef_grill", "coke"),
    _lit("PlaceOccludedBy", "sprite", "behind_of", "beef_grill", "beef_grill"),
    _lit("PlaceOccludedBy", "sprite", "behind_of", "mango_juice", "dr_pepper"),
    _lit("PlaceOccludedBy", "mango_juice", "left_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "mango_juice", "right_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "mango_juice", "behind_of", "coke", "coke"),
    _lit("PlaceOccludedBy", "mango_juice", "behind_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "mango_juice", "behind_of", "beef_grill", "coke"),
    _lit("PlaceOccludedBy", "mango_juice", "behind_of", "beef_grill", "beef_grill"),
    _lit("PlaceOccludedBy", "mango_juice", "behind_of", "sprite", "sprite"),
    _lit("PlaceOccludedBy", "mango_juice", "front_of", "dr_pepper", "dr_pepper"),
    _lit("PlaceOccludedBy", "dr_pepper", "on", "counter2", "beef_grill"),
    _lit("PlaceOccludedBy", "dr_pepper", "left_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "dr_pepper", "right_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "dr_pepper", "behind_of", "coke", "coke"),
    _lit("PlaceOccludedBy", "dr_pepper", "behind_of", "coke", "beef_grill"),
    _lit("PlaceOccludedBy", "dr_pepper", "behind_of", "beef_grill", "coke"),
    _lit("PlaceOccludedBy", "dr_pepper", "behind_of", "beef_grill", "beef_grill"),
)
