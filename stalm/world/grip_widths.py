"""How wide the gripper must open to take each object, and why one it cannot take never moves.

A grasp closes the fingers horizontally (the gripper's closing axis stays level at every
pitch), so what must fit between them is the object's horizontal width across the closing
direction at the narrowest grasp its shape offers: a can's diameter, a grill handle's bar, a
plate's rim, a box's narrower side. An object wider than the gripper opens along every closing
direction can never be picked: it stays where it stands, as clutter, and the problem checks
that warn of objects that can never move name its width beside the gripper's opening.
"""

from __future__ import annotations

from stalm.world.spec import GRILL_HANDLE_HALF_HEIGHT, ObjectSpec


def narrowest_grip(obj: ObjectSpec) -> float:
    """The least opening (m) any grasp of ``obj``'s shape needs."""
    if obj.shape == "box":
        assert obj.size is not None
        return min(obj.size[0], obj.size[1])
    if obj.shape == "grill":
        return 2 * GRILL_HANDLE_HALF_HEIGHT  # the handle's bar, across its depth
    assert obj.radius is not None and obj.height is not None
    if obj.shape == "disc":
        return obj.height  # a plate is pinched at its rim
    return 2 * obj.radius


def too_wide(obj: ObjectSpec, gap: float) -> str | None:
    """Why no grasp of a gripper opening ``gap`` metres fits ``obj`` (in words), or None."""
    width = narrowest_grip(obj)
    if width <= gap:
        return None
    return (
        f"it is {width:.3g} m across at its narrowest, wider than the gripper opens "
        f"({gap:.3g} m): no grasp fits it"
    )
