"""The scene's words every layer shares: the roles of its masks and the model hand's size.

A mask's role is ``hand``, ``object`` (the manipulated object) or ``static_k`` (static
object k, from 0); ``static`` names them all (a palette entry, a pooled score). The model
hand is the cylinder the engine simulates and renders, the Rerun recording draws and the
footage path draws along a found hand: 40 cm long and 8 cm across, a hand with its forearm
(a real adult hand's size is :mod:`warpskill.nouns.typical`'s).
"""

from __future__ import annotations

HAND, OBJECT, STATIC = "hand", "object", "static"
"""Role names: the hand, the manipulated object, and the static objects as a kind."""

MODEL_HAND_LENGTH = 0.40
"""Length [m] of the model hand's cylinder, fingertips to forearm."""

MODEL_HAND_RADIUS = 0.04
"""Radius [m] of the model hand's cylinder."""


def static_role(k: int) -> str:
    """The role of static object ``k`` (from 0): ``static_k``."""
    return f"{STATIC}_{k}"


def role_kind(role: str) -> str:
    """``hand``, ``object`` or ``static`` (for any ``static_k``)."""
    return STATIC if role.startswith(STATIC) else role


def role_order(role: str) -> tuple[int, int]:
    """Sort key: the hand, the object, then the static objects by index."""
    if role == HAND:
        return (0, 0)
    if role == OBJECT:
        return (1, 0)
    return (2, int(role.rsplit("_", 1)[1]))
