"""The hand as a second ruler: an object's apparent size against the hand's, in the frames they touch."""

import dataclasses

import numpy as np
import pytest

from warpskill.bench.rulers import hand_ruled_size, hand_ruler_ratio
from warpskill.nouns.typical import HAND_LENGTH
from warpskill.synthetic import make_demonstration


def boxed(demo, hand_box, object_box, touching):
    """``demo`` with box masks (rows, cols: (top, left, bottom, right) [px]) and contact in ``touching`` frames."""
    hand, thing = np.zeros_like(demo.hand_mask), np.zeros_like(demo.object_mask)
    (t, l, b, r), (t2, l2, b2, r2) = hand_box, object_box
    hand[:, t:b, l:r] = True
    thing[:, t2:b2, l2:r2] = True
    contact = np.zeros(demo.num_frames, dtype=bool)
    contact[touching] = True
    return dataclasses.replace(demo, hand_mask=hand, object_mask=thing, contact=contact)


def test_the_hand_measures_the_object_in_the_frames_it_touches_it():
    demo = make_demonstration("pick_up", seed=0, noise="none")
    # A hand 95 px long, an object 50 px across its longer side: 50/95 of a hand's length.
    demo = boxed(demo, (100, 100, 140, 195), (120, 150, 170, 180), slice(10, 30))
    assert hand_ruled_size(demo) == pytest.approx(50 / 95 * HAND_LENGTH)
    assert hand_ruler_ratio(np.array([0.02, 0.05, 0.2]), demo) == pytest.approx(0.2 / (50 / 95 * HAND_LENGTH))


def test_without_the_hand_in_the_touching_frames_the_hand_measures_nothing():
    demo = make_demonstration("pick_up", seed=0, noise="none")
    handless = boxed(demo, (100, 100, 140, 195), (120, 150, 170, 180), slice(10, 30))
    handless.hand_mask[10:30] = False  # the hand hidden (out of view) wherever it touches the object
    assert hand_ruled_size(handless) is None
    assert hand_ruler_ratio(np.array([0.1, 0.1, 0.1]), handless) is None
