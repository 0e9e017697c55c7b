"""Mask measurements (``warpskill.optimizer.measurements``) on masks drawn here, with known answers."""

import numpy as np
import pytest

from warpskill.engine.primitives import HAND_LENGTH, HAND_RADIUS
from warpskill.optimizer.measurements import (
    MAX_HAND_TILT,
    TYPICAL_HAND_TILT,
    MaskGeometry,
    band_width,
    fill_missing,
    hand_depth,
    hand_tilt,
)

FOCAL = 200.0  # [px], square pixels
K = np.array([[FOCAL, 0.0, 80.0], [0.0, FOCAL, 60.0], [0.0, 0.0, 1.0]])


def band(length: int, width: int, *, row: int = 40, col: int = 30, frames: int = 1) -> np.ndarray:
    """Masks (frames, 120, 160) of a horizontal band ``length`` x ``width`` px from (row, col)."""
    masks = np.zeros((frames, 120, 160))
    masks[:, row : row + width, col : col + length] = 1.0
    return masks


def test_geometry_reads_visibility_centroid_box_and_pixels():
    masks = np.zeros((3, 20, 30))
    masks[0, 2:6, 10:20] = 1.0
    masks[2, 0:1, 0:2] = 0.7  # above the 0.5 threshold
    masks[2, 5, 5] = 0.4  # below it
    geom = MaskGeometry(masks)
    assert geom.visible.tolist() == [True, False, True]
    np.testing.assert_allclose(geom.centroid[0], [15.0, 4.0])  # pixel centres (u, v)
    np.testing.assert_allclose(geom.box[0], [10.0, 2.0, 20.0, 6.0])  # pixel edges
    assert np.isnan(geom.centroid[1]).all() and np.isnan(geom.box[1]).all()
    np.testing.assert_allclose(geom.pixels(2), [[0.5, 0.5], [1.5, 0.5]])


def test_missing_frames_take_the_nearest_valid_frames_value():
    values = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    valid = np.array([False, True, False, False, True])
    assert fill_missing(values, valid).tolist() == [1.0, 1.0, 1.0, 4.0, 4.0]  # a tie takes the earlier frame
    with pytest.raises(ValueError, match="no valid frame"):
        fill_missing(values, np.zeros(5, dtype=bool))


def test_band_width_is_a_uniform_bands_width():
    points = np.stack(np.meshgrid(np.arange(40) + 0.5, np.arange(10) + 0.5), -1).reshape(-1, 2)
    assert band_width(points, np.array([1.0, 0.0])) == pytest.approx(40.0, rel=1e-3)
    assert band_width(points, np.array([0.0, 1.0])) == pytest.approx(10.0, rel=1e-2)


@pytest.mark.parametrize("width", [8, 16, 24])
def test_the_hand_depth_is_where_a_cylinder_of_the_hands_radius_is_that_wide(width):
    masks = band(60, width)
    tip = np.array([[140.0, 45.0]])  # the object, right of the band: its tip is the right end
    expected = 2.0 * HAND_RADIUS * FOCAL / width  # [m]
    assert hand_depth(MaskGeometry(masks), tip, K) == pytest.approx(expected, rel=0.01)


def test_the_hand_depth_is_read_at_the_tip_where_a_hand_reaching_forwards_is_thinnest():
    masks = band(60, 10)
    masks[0, 25:65, 30:60] = 1.0  # its far half, nearer the camera, 40 px wide
    tip = np.array([[140.0, 45.0]])
    assert hand_depth(MaskGeometry(masks), tip, K) == pytest.approx(2.0 * HAND_RADIUS * FOCAL / 10, rel=0.05)


def test_hand_depth_is_the_median_over_frames_and_none_without_a_readable_band():
    masks = np.concatenate([band(60, 10), band(60, 20), band(60, 20)])
    tip = np.full((3, 2), [140.0, 45.0])
    assert hand_depth(MaskGeometry(masks), tip, K) == pytest.approx(2.0 * HAND_RADIUS * FOCAL / 20, rel=0.01)
    sliver = np.zeros((1, 120, 160))
    sliver[0, 40, 30:33] = 1.0  # fewer pixels than a width can be read from
    assert hand_depth(MaskGeometry(sliver), tip[:1], K) is None
    assert hand_tilt(MaskGeometry(sliver), K) is None


@pytest.mark.parametrize("length", [50, 60, 80])
def test_a_foreshortened_hand_leans_towards_the_camera(length):
    width = 20
    slenderness = HAND_LENGTH / (2.0 * HAND_RADIUS)  # the cylinder's length over its diameter
    expected = np.sqrt(1.0 - (length / (slenderness * width)) ** 2)
    assert TYPICAL_HAND_TILT < expected < MAX_HAND_TILT
    assert hand_tilt(MaskGeometry(band(length, width)), K) == pytest.approx(expected, abs=0.01)


def test_the_lean_stays_between_a_typical_forearms_and_its_upper_bound():
    slenderness = HAND_LENGTH / (2.0 * HAND_RADIUS)
    whole = band(int(slenderness * 20), 20)  # the full length in view: in the image plane
    assert hand_tilt(MaskGeometry(whole), K) == TYPICAL_HAND_TILT
    stub = band(20, 20)  # as long as wide: cut by the border or seen end-on
    assert hand_tilt(MaskGeometry(stub), K) == MAX_HAND_TILT
