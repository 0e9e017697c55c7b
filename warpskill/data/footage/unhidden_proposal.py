"""The frame where the hand does not hide what it touches, for the outline's proposal.

An object the hand presses, pokes or holds in place without carrying it lies in the same
place before the hand comes (and, unless pushed, after it leaves); there it is seen whole, where at the touch
the fingers cover it (a small toy under a fingertip, a book's lower half under the hand).
:func:`unhidden_view` finds the frame nearest to the touch in which no hand lies near the
touched points, and where those points are there (the camera's motion between the two frames
fitted as a homography to corners tracked outside the hands). OpenCV and NumPy only.
"""

from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

from warpskill.data.footage.tracking import CAMERA_CORNERS, CAMERA_RANSAC_PX, carried_corners

MIN_CAMERA_INLIERS = 12
"""Fewest corners agreeing with the camera's homography between the touch and another frame
for the points to be placed there (fewer: the frames are not registered, the frame is skipped)."""

HAND_MARGIN_PX = 7
"""Width [px] the hands are widened by before corners are taken off them (a hand's edge
moves with the hand, not with the camera)."""


def unhidden_view(frames: np.ndarray, key: int, points: np.ndarray, hands_of: Callable[[int], np.ndarray],
                  reach: float) -> tuple[int, np.ndarray] | None:
    """The frame nearest before ``key`` (else nearest after it) in which every hand lies
    farther than ``reach`` from ``points`` carried there by the camera's motion, and the
    points there: before the touch the object lies where it was touched; after it, a pushed
    one may have moved.

    Args:
        frames: (N, H, W, 3) uint8 RGB frames.
        key: the frame the hand touches the object in.
        points: (M, 2) [px] (x, y) points of frame ``key`` (where the object was seeded).
        hands_of: frame index -> (H, W) bool, every hand seen in it.
        reach: least distance [px] of any hand from every carried point.

    Returns:
        The frame and the (M, 2) points [px] there; None where no frame is clear of the hands
        with the points inside the image and the camera's motion fitted.
    """
    n, h, w = frames.shape[:3]
    key_grey = cv2.cvtColor(frames[key], cv2.COLOR_RGB2GRAY)
    corners = CAMERA_CORNERS.find(key_grey, _off(hands_of(key)))
    if corners is None or len(corners) < MIN_CAMERA_INLIERS:
        return None
    for j in [*range(key - 1, -1, -1), *range(key + 1, n)]:
        hands = hands_of(j)
        if _distance_to(hands, points) <= reach:  # the camera moves little: a quick test first
            continue
        homography = _camera_motion(key_grey, cv2.cvtColor(frames[j], cv2.COLOR_RGB2GRAY), corners)
        if homography is None:
            continue
        carried = cv2.perspectiveTransform(points.reshape(-1, 1, 2).astype(np.float64), homography).reshape(-1, 2)
        inside = ((carried >= 0) & (carried < [w, h])).all()
        if inside and _distance_to(hands, carried) > reach:
            return j, carried
    return None


def _off(hands: np.ndarray) -> np.ndarray:
    """(H, W) uint8: 1 off the ``hands`` (H, W) bool widened by :data:`HAND_MARGIN_PX`, else 0."""
    width = 2 * HAND_MARGIN_PX + 1
    return 1 - cv2.dilate(hands.astype(np.uint8), np.ones((width, width), np.uint8))


def _distance_to(mask: np.ndarray, points: np.ndarray) -> float:
    """Least distance [px] from ``points`` (M, 2) (x, y) to ``mask`` (H, W) bool; inf where it is empty."""
    if not mask.any():
        return float("inf")
    h, w = mask.shape
    distance = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 3)
    xs, ys = np.clip(points, 0, [w - 1, h - 1]).astype(int).T
    return float(distance[ys, xs].min())


def _camera_motion(before: np.ndarray, after: np.ndarray, corners: np.ndarray) -> np.ndarray | None:
    """(3, 3) homography from grey frame ``before``'s pixels to ``after``'s, fitted (RANSAC) to
    ``corners`` (M, 1, 2) tracked with Lucas-Kanade; None where fewer than
    :data:`MIN_CAMERA_INLIERS` agree."""
    source, target = carried_corners(before, after, corners)
    if len(source) < MIN_CAMERA_INLIERS:
        return None
    homography, inliers = cv2.findHomography(source, target, cv2.RANSAC, CAMERA_RANSAC_PX)
    if homography is None or inliers is None or int(inliers.sum()) < MIN_CAMERA_INLIERS:
        return None
    return homography
