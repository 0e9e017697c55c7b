"""Mask clean-up: largest blob, specks, subsampling."""

import numpy as np
import pytest

from warpskill.data.masks import clean_masks, drop_specks, largest_component, subsample


def _frames():
    masks = np.zeros((3, 20, 20), dtype=bool)
    masks[0, 2:10, 2:10] = True  # 64 px blob
    masks[0, 15:17, 15:17] = True  # 4 px speck beside it
    masks[1, 5:13, 5:13] = True
    masks[2, 0:2, 0:1] = True  # a whole frame that is only a speck
    return masks


def test_largest_component_keeps_the_biggest_blob_per_frame():
    out = largest_component(_frames())
    assert out[0].sum() == 64 and not out[0, 15:17, 15:17].any()
    assert out[1].sum() == 64 and out[2].sum() == 2


def test_drop_specks_empties_frames_far_below_the_typical_area():
    out = drop_specks(largest_component(_frames()), 0.1)
    assert out[0].sum() == 64 and out[1].sum() == 64 and not out[2].any()
    assert np.array_equal(clean_masks(_frames(), 0.1), out)
    assert drop_specks(np.zeros((2, 4, 4), dtype=bool)).sum() == 0
    with pytest.raises(ValueError, match="min_fraction"):
        drop_specks(_frames(), 1.5)


def test_the_default_clean_up_keeps_a_small_frame():
    # An object going behind another shows as a sliver: evidence, not a speck.
    out = clean_masks(_frames())
    assert out[2].sum() == 2 and out[0].sum() == 64


def test_subsample_in_space_and_time():
    out = subsample(_frames(), spatial=2, temporal=2)
    assert out.shape == (2, 10, 10)
    assert out[0, 1:5, 1:5].all() and out[0].sum() == 16  # the speck covers a quarter of 4 blocks
    assert subsample(_frames()).shape == (3, 20, 20)
    with pytest.raises(ValueError, match="spatial"):
        subsample(_frames(), spatial=0)
    with pytest.raises(ValueError, match="temporal"):
        subsample(_frames(), temporal=1.5)


def test_masks_must_be_n_h_w_bool():
    with pytest.raises(ValueError, match=r"\(N, H, W\)"):
        largest_component(np.zeros((4, 4), dtype=bool))
    with pytest.raises(ValueError, match="bool"):
        clean_masks(np.zeros((1, 4, 4), dtype=np.uint8))
