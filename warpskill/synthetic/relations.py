"""The relations scenario: put actions and pick-ups as a phone films them on a table.

Static objects with real nouns at about their typical sizes, flat (a book, a plate, a tray)
and tall (a box, a bowl, a cereal box), often reaching out of the view; objects put onto, beside,
behind and in front of them (behind a tall static the object's box is partly or wholly
hidden); pick-ups of small and flat objects (a phone, a pen, a key, a card); a camera low
over the table. Every case reaches the optimiser through the Something-Else box reader,
its boxes labelled with the nouns, as an annotated real video does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warpskill.contract.actions import ACTIONS
from warpskill.nouns.typical import typical_size
from warpskill.synthetic.scripts import TIP_DEPTH, Variant, draw_variant

RELATION_ACTIONS = ("pick_up", "put_behind", "put_in_front_of", "put_next_to", "put_onto")
"""The actions of the relations scenario: those that relate the object to a static or lift it."""

FLAT_STATICS = ("book", "plate", "tray", "cutting board", "laptop", "notebook")
TALL_STATICS = ("box", "shoebox", "tissue box", "bowl", "cereal box")
"""Nouns of the static objects, flat and tall (their sizes from :func:`~warpskill.nouns.typical.typical_size`)."""

PUT_OBJECTS = ("cup", "mug", "apple", "can", "jar", "candle", "orange", "mouse", "tape", "glass", "bottle",
               "wallet", "matchbox", "stapler")
"""Nouns of the objects that put actions move (mugs and cups wider than the Panda's gripper among them)."""

PICKED_OBJECTS = ("phone", "pen", "key", "card", "remote", "wallet", "lighter", "eraser")
"""Nouns of the small and flat objects that pick-ups lift."""

SIZE_SPREAD = 0.15
"""Each edge is its noun's typical edge times a factor drawn in 1 +- SIZE_SPREAD."""

MIN_HEIGHT = 0.01
"""[m] the least height of a scene's cuboid: the engine's grasp switch (a sigmoid of width
``PhysicsConfig.grasp_tau``, 1 mm) holds an object only with the tip some 5 mm inside it, so a
card or a key is as thick as this."""

SIDE_REACH_BELOW = 0.03
"""[m] an object lower than this is reached from the side (``Variant.side_reach``): from the
camera's side the model hand, a 4 cm cylinder, would hide it while it holds it."""

OUT_OF_VIEW_SHARE = 0.4
OUT_OF_VIEW_SHIFT = (0.3, 0.7)
"""The share of put behind / in front of / next to scenes whose static stands farther from the
object, by this range of its width, so that the frame often cuts it (the object stays in view)."""

CAMERA_ELEVATION = (0.3, 0.55)
"""[rad] range of the camera's elevation: lower than the default scenes', as a phone over a table."""

RELATION_SPOILERS = {"hand_partly_seen": 0.3, "enters_view": 0.15}
"""The annotation situations mixed in (``enters_view`` for put actions only), each with its probability.
Not ``static_cut_by_frame``: its box stretched to the border would make a named static wider than
its noun; here a static is cut by the frame where it really reaches out of the view (a tray, a
cutting board)."""


@dataclass(frozen=True)
class RelationCase:
    """What the relations scenario draws for one case: the scene's variant, the nouns, the
    camera's elevation [rad] and the annotation spoilers."""

    variant: Variant
    object_noun: str
    static_noun: str | None
    camera_elevation: float
    spoilers: tuple[str, ...]


def relation_case(action: str, seed: int) -> RelationCase:
    """The relations scenario's draw for ``action`` at ``seed`` (deterministic; its own random stream).

    Raises:
        ValueError: for an action outside :data:`RELATION_ACTIONS`.
    """
    if action not in RELATION_ACTIONS:
        raise ValueError(f"scenario 'relations' takes {', '.join(RELATION_ACTIONS)}; got {action!r}")
    rng = np.random.default_rng([seed, ACTIONS.index(action), 3])
    placed = action != "pick_up"
    object_noun = str(rng.choice(PUT_OBJECTS if placed else PICKED_OBJECTS))
    size = _noun_size(object_noun, rng)
    size = (size[0], size[1], max(size[2], MIN_HEIGHT))
    static_noun = str(rng.choice(FLAT_STATICS if rng.random() < 0.5 else TALL_STATICS)) if placed else None
    static_size = _noun_size(static_noun, rng) if placed else None
    variant = draw_variant(action, seed, rng)
    away = 0.0
    if placed and action != "put_onto" and rng.random() < OUT_OF_VIEW_SHARE:
        away = float(rng.uniform(*OUT_OF_VIEW_SHIFT)) * static_size[0]
    variant = Variant(ending=variant.ending, far_start=variant.far_start, object_size=size, static_size=static_size,
                      clear_static=True, static_away=away, tip_depth=min(TIP_DEPTH, 0.5 * size[2]),
                      side_reach=size[2] < SIDE_REACH_BELOW)
    spoilers = tuple(name for name, p in RELATION_SPOILERS.items()
                     if (placed or name == "hand_partly_seen") and rng.random() < p)
    return RelationCase(variant, object_noun, static_noun, float(rng.uniform(*CAMERA_ELEVATION)), spoilers)


def _noun_size(noun: str, rng: np.random.Generator) -> tuple[float, float, float]:
    """Edges (x, y, z) [m] of an object named ``noun``: width, depth, height of its typical size, spread."""
    typical = typical_size(noun)
    if typical is None:  # pragma: no cover - the noun lists above are in the table
        raise KeyError(f"no typical size for {noun!r}")
    edges = np.array([typical.width, typical.depth, typical.height])
    return tuple(float(v) for v in edges * rng.uniform(1 - SIZE_SPREAD, 1 + SIZE_SPREAD, 3))
