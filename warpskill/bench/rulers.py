"""The hand as a second ruler: an object's apparent size measured against the hand that holds it.

Where the hand touches the object, both are at about the same distance from the camera, so
the ratio of their apparent sizes is (roughly) the ratio of their real sizes, and a hand's
length is known (:data:`~warpskill.nouns.typical.HAND_LENGTH`). The figure is independent
of the optimiser's scale (its camera prior, the noun prior) and of the noun table: a second
opinion on a reconstructed object's size where there is no ground truth. Rough by nature:
a hand's box is its visible part, a box's longer side only an object's projection.
"""

from __future__ import annotations

import numpy as np

from warpskill.contract.demonstration import Demonstration
from warpskill.nouns.typical import HAND_LENGTH

__all__ = ["hand_ruled_size", "hand_ruler_ratio"]


def _longer_side(mask: np.ndarray) -> float:
    """[px] the longer side of a mask's bounding box (0 for an empty mask)."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if len(rows) == 0:
        return 0.0
    return float(max(rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1))


def hand_ruled_size(demo: Demonstration) -> float | None:
    """[m] the object's largest apparent extent measured with the hand, or None without a frame to measure.

    Per frame with contact and both masks present: the longer side of the object mask's
    bounding box over the hand mask's, times :data:`HAND_LENGTH`; the median over those frames.
    """
    ratios = []
    for k in np.flatnonzero(np.asarray(demo.contact) > 0.5):
        hand, thing = _longer_side(demo.hand_mask[k]), _longer_side(demo.object_mask[k])
        if hand > 0 and thing > 0:
            ratios.append(thing / hand)
    return float(np.median(ratios)) * HAND_LENGTH if ratios else None


def hand_ruler_ratio(object_size: np.ndarray, demo: Demonstration) -> float | None:
    """How many times larger the reconstructed object (edges (3,) [m]) is than the hand measures it
    (its largest edge over :func:`hand_ruled_size`); None where the hand measures nothing."""
    ruled = hand_ruled_size(demo)
    return None if ruled is None else float(np.max(object_size) / ruled)
