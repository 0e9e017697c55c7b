"""Contact estimation: detections CSV, detections from masks, and each step of the filter."""

import numpy as np
import pytest

from warpskill.data.contact import (
    IN_CONTACT as C,
)
from warpskill.data.contact import (
    NO_CONTACT as N,
)
from warpskill.data.contact import (
    UNKNOWN as U,
)
from warpskill.data.contact import (
    advance_release,
    detections_from_masks,
    estimate_contact,
    extend_to_ends,
    filter_contact,
    smooth_detections,
)
from warpskill.data.readers.contact_files import read_detections


def _object(xs, size=6, h=20, w=60):
    """An object mask whose left edge is at xs[k] in frame k (None: not visible)."""
    masks = np.zeros((len(xs), h, w), dtype=bool)
    for k, x in enumerate(xs):
        if x is not None:
            masks[k, 8 : 8 + size, x : x + size] = True
    return masks


def test_read_detections(tmp_path):
    path = tmp_path / "contact.csv"
    path.write_text("frame,in_contact,score\n0,1,0.9\n1,0,0.8\n3,true,0.2\n4,1,\n")
    assert read_detections(path, 6).tolist() == [C, N, U, U, C, U]  # 3: score below 0.5


@pytest.mark.parametrize("content, match", [
    ("frame,contact\n0,1\n", "missing column"),
    ("frame,in_contact\n9,1\n", "line 2: frame 9 outside"),
    ("frame,in_contact\n0,1\n0,0\n", "line 3: frame 0 listed twice"),
    ("frame,in_contact\n0,yes\n", "line 2: column in_contact"),
    ("frame,in_contact\nfirst,1\n", "column frame"),
])
def test_read_detections_rejects_malformed_files(tmp_path, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(ValueError, match=match) as error:
        read_detections(path, 5)
    assert str(path) in str(error.value)


def test_detections_from_masks():
    obj = _object([30, 30, 30, 36, None])
    hand = np.zeros_like(obj)
    hand[0, 8:14, 10:15] = True  # far away: no contact
    hand[1, 8:14, 25:29] = True  # 1 px gap: touching within 2 px
    hand[2, 0:3, 0:3] = True  # far, object still
    hand[3, 0:3, 0:3] = True  # far, but the object moved 6 px: held
    hand[4, 0:3, 0:3] = True  # object not visible
    assert detections_from_masks(hand, obj).tolist() == [N, C, N, C, U]


def test_step_a_majority_smoothing():
    detections = np.array([C, C, C, N, C, C, C, N, N, N, C, N, N, N])  # two isolated flips
    assert smooth_detections(detections).tolist() == [C, C, C, C, C, C, C, N, N, N, N, N, N, N]
    # a removed positive becomes a negative; an unknown frame the vote turns positive, a positive
    assert smooth_detections(np.array([U, U, C, U, U, C, C, C, U])).tolist() == [U, U, N, U, C, C, C, C, C]
    with pytest.raises(ValueError, match="values"):
        smooth_detections(np.array([0, 2]))


def test_step_b_moving_object_is_held_from_the_start_until_the_first_negative():
    detections = np.array([U, U, U, N, N, C, C, N, N, U])
    moving_start = _object([0, 3, 6, 9, 9, 9, 9, 9, 9, 9])
    assert extend_to_ends(detections, moving_start).tolist() == [C, C, C, N, N, C, C, N, N, U]
    moving_end = _object([0, 0, 0, 0, 0, 0, 0, 4, 8, 12])
    assert extend_to_ends(detections, moving_end).tolist() == [U, U, U, N, N, C, C, N, N, C]
    still = _object([5] * 10)
    assert np.array_equal(extend_to_ends(detections, still), detections)


def test_step_c_release_moves_to_where_the_object_stops():
    contact = np.array([0, 1, 1, 1, 1, 1, 1, 1, 0, 0], dtype=bool)
    obj = _object([0, 0, 3, 6, 9, 9, 9, 9, 9, 9])  # moves into frames 2-4, still from 5
    assert advance_release(contact, obj).astype(int).tolist() == [0, 1, 1, 1, 1, 1, 0, 0, 0, 0]
    held_to_the_end = np.array([0, 1, 1, 1, 1, 1, 1, 1, 1, 1], dtype=bool)  # no release seen
    assert np.array_equal(advance_release(held_to_the_end, obj), held_to_the_end)


def test_filter_and_estimate():
    detections = np.array([N, N, C, C, C, U, U, U, C, C, C, N, N])
    obj = _object([0, 0, 0, 3, 6, 9, 12, 15, 18, 18, 18, 18, 18])  # moves into frames 3-8
    # (a) keeps both runs, the unknown frames 5-7 between them become contact, (c) ends it at 9
    assert filter_contact(detections, obj).astype(int).tolist() == [0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0]
    hand = np.zeros_like(obj)
    hand[:, 0:3, 40:50] = True  # seen, away from the object
    hand[3:9] = np.roll(obj[3:9], -6, axis=2)  # touching the object's left side while it moves
    contact = estimate_contact(hand, obj)
    assert contact[3:9].all() and not contact[:2].any() and not contact[-2:].any()
