"""Sparse corners carried from one frame to the next: the one Lucas-Kanade step that the
object follower, the hand follower and the camera's motion share. NumPy and OpenCV only."""

from __future__ import annotations

import cv2
import numpy as np

LK_WINDOW_PX = 15
"""Side [px] of the Lucas-Kanade window."""

LK_LEVELS = 4
"""Pyramid levels of Lucas-Kanade above the full frame (motions up to ~15 x 2^4 px a frame)."""

ROUND_TRIP_PX = 1.0
"""A corner is kept when tracking it forward then back returns within this [px] of where it started."""


def carried_corners(before: np.ndarray, after: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corners of grey frame ``before`` and their places in ``after``, tracked with
    pyramidal Lucas-Kanade and kept where tracking back returns to the start.

    Args:
        before, after: (H, W) uint8 grey frames.
        corners: (M, 1, 2) float32 corners [px] in ``before`` (``cv2.goodFeaturesToTrack``'s shape).

    Returns:
        Two (K, 2) float32 arrays [px]: the kept corners and where they went.
    """
    params = dict(winSize=(LK_WINDOW_PX, LK_WINDOW_PX), maxLevel=LK_LEVELS)
    ahead, ok, _ = cv2.calcOpticalFlowPyrLK(before, after, corners, None, **params)
    back, ok_back, _ = cv2.calcOpticalFlowPyrLK(after, before, ahead, None, **params)
    good = (ok[:, 0] == 1) & (ok_back[:, 0] == 1) & (np.linalg.norm(back - corners, axis=2)[:, 0] < ROUND_TRIP_PX)
    return corners[good, 0], ahead[good, 0]
