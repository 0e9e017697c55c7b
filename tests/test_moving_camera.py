"""A camera that moves shows in the static boxes: they wander at a steady size, and one line says so."""

import logging

import numpy as np

from warpskill.contract.demonstration import Demonstration
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.inputs import static_box_drift
from warpskill.optimizer.pipeline import optimize

N, H, W = 20, 60, 100
CONTACT = (np.arange(N) >= 4) & (np.arange(N) < 12)
FAST = OptimizeConfig(iterations=1, init_iterations=1)


def _masks(static_at, static_size=lambda k: (14, 20)):
    """(N, 3, H, W) masks: a hand at the top, an object carried onto the right, a static box whose
    top-left corner in frame k is ``static_at(k)`` (row, column) and size ``static_size(k)``."""
    masks = np.zeros((N, 3, H, W), dtype=np.float32)
    masks[:12, 0, 0:10, 70:76] = 1
    for k in range(N):
        r0, c0 = (10, 60) if k < 12 else (30, 70)
        masks[k, 1, r0:r0 + 8, c0:c0 + 10] = 1
        (r, c), (h, w) = static_at(k), static_size(k)
        masks[k, 2, r:r + h, c:c + w] = 1
    return masks


def test_a_static_box_that_wanders_at_a_steady_size_measures_the_camera_motion():
    assert static_box_drift(_masks(lambda k: (30, 20))) == 0.0
    panned = _masks(lambda k: (30, 20 + k))  # one column a frame: 19 px in all
    assert static_box_drift(panned) == 19.0
    tilted = _masks(lambda k: (30 - k // 2, 20 + k))  # and up 9 rows
    assert np.isclose(static_box_drift(tilted), np.hypot(19, 9))
    assert static_box_drift(panned[:, :2]) == 0.0  # no static box


def test_a_static_box_that_changes_size_or_meets_the_border_measures_nothing_there():
    # The object covers its lower half from frame 12 on: the visible box shrinks, its centre
    # rises, yet nothing moved.
    covered = _masks(lambda k: (30, 20), lambda k: (14, 20) if k < 12 else (7, 20))
    assert static_box_drift(covered) == 0.0
    # Cut by the left border from frame 12 on: its centre shifts right, the camera did not.
    cut = _masks(lambda k: (30, 20), lambda k: (14, 20))
    cut[12:, 2] = 0
    cut[12:, 2, 30:44, 0:12] = 1
    assert static_box_drift(cut) == 0.0


def test_a_demonstration_filmed_by_a_moving_camera_is_told_so(caplog):
    def demo(static_at):
        masks = _masks(static_at) > 0.5
        return Demonstration.from_arrays(masks[:, 0], masks[:, 1], CONTACT, 12.0, static_mask=masks[:, 2][None],
                                         action="put_next_to")

    with caplog.at_level(logging.WARNING, logger="warpskill.optimizer.pipeline"):
        optimize(demo(lambda k: (30, 20 + k)), config=FAST, init_only=True, progress=False)
    assert "a static object's box moves 19 px (19 % of the width)" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="warpskill.optimizer.pipeline"):
        optimize(demo(lambda k: (30, 20 + k % 2)), config=FAST, init_only=True, progress=False)
    assert "camera" not in caplog.text  # a pixel of jitter is no camera motion
