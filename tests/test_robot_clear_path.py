"""The robot's held-object path: never inside its support, no steps down (``sizes.clear_path``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from warpskill.contract.reconstruction import Reconstruction
from warpskill.robot.sizes import DESCENT_SPEED, clear_path
from warpskill.synthetic import make_demonstration


@pytest.fixture(scope="module")
def put_onto() -> Reconstruction:
    return Reconstruction(**make_demonstration("put_onto", seed=0, noise="none").truth)


def held_span(recon: Reconstruction) -> slice:
    held = np.flatnonzero(recon.grasped > 0.5)
    return slice(int(held[0]), int(held[-1]) + 2)


def with_heights(recon: Reconstruction, frames: slice, z: np.ndarray | float) -> Reconstruction:
    """``recon`` with the object (and the hand, by as much) at heights ``z`` in ``frames``."""
    object_pos, hand_pos = recon.object_pos.copy(), recon.hand_pos.copy()
    shift = z - object_pos[frames, 2]
    object_pos[frames, 2] += shift
    hand_pos[frames, 2] += shift
    return dataclasses.replace(recon, object_pos=object_pos, hand_pos=hand_pos)


def resting_centre(recon: Reconstruction) -> float:
    """[m] the centre height of the object standing on the table in its first frame's orientation."""
    return float(0.5 * np.abs(recon.object_rot[0, 2]) @ recon.object_size)


def test_a_held_object_sunk_into_the_table_rests_on_it_and_the_hand_rises_with_it(put_onto):
    span = held_span(put_onto)
    onset = span.start
    z0 = resting_centre(put_onto)
    sunk = with_heights(put_onto, slice(onset, onset + 1), z0 - 0.02)
    cleared = clear_path(sunk)
    assert cleared.object_pos[onset, 2] == pytest.approx(z0, abs=1e-3)
    np.testing.assert_allclose(cleared.hand_pos - cleared.object_pos, sunk.hand_pos - sunk.object_pos, atol=1e-12)
    # Only the held span moves: before the onset the object is as reconstructed.
    np.testing.assert_array_equal(cleared.object_pos[:onset], sunk.object_pos[:onset])
    np.testing.assert_array_equal(cleared.object_pos[:, :2], sunk.object_pos[:, :2])


def test_a_held_object_stepping_down_descends_at_most_at_the_descent_speed(put_onto):
    span = held_span(put_onto)
    middle = (span.start + span.stop) // 2
    z0 = resting_centre(put_onto)
    high, low = z0 + 0.25, z0 + 0.01  # carried high, then a step of 24 cm within a frame
    z = np.where(np.arange(span.start, span.stop) < middle, high, low)
    stepped = with_heights(put_onto, span, z)
    stepped.object_pos[span, :2] = stepped.object_pos[span.start, :2] + np.array([0.3, 0.3])  # clear of the static box
    cleared = clear_path(stepped)
    path = cleared.object_pos[span, 2]
    speed = -np.diff(path) * float(put_onto.fps)
    assert speed.max() <= DESCENT_SPEED + 1e-9
    assert np.all(path >= stepped.object_pos[span, 2] - 1e-12)  # only ever raised
    assert path[middle - span.start - 1] == pytest.approx(high)  # the carry itself is kept
    assert path[middle - span.start] == pytest.approx(high - DESCENT_SPEED / float(put_onto.fps))


def test_a_path_already_clear_is_returned_unchanged(put_onto):
    lifted = with_heights(put_onto, held_span(put_onto), put_onto.object_pos[held_span(put_onto), 2] + 0.01)
    assert clear_path(lifted) is lifted
