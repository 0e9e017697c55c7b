"""The frame where the hand does not hide what it touches, for the outline's proposal.

An object the hand presses, pokes or holds in place without carrying it lies in the same
place before the hand comes (and, unless pushed, after it leaves); there it is seen whole,
where at the touch the fingers cover it (a small toy under a fingertip). :func:`unhidden_view`
finds the frame nearest to the touch in which no hand lies near the touched points, and where
those points are there (the camera's motion fitted from frame to frame as a homography to
corners tracked off the hands). OpenCV and NumPy only.
"""

from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

from warpskill.data.footage.tracking import CAMERA_CORNERS, CAMERA_RANSAC_PX, carried_corners

MIN_CAMERA_INLIERS = 12
"""Fewest corners agreeing with the camera's homography between two frames for the points to
be carried on (fewer: the frames are not registered, and the search stops on that side)."""

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
        with the points inside the image, the camera's motion fitted from frame to frame.
    """
    n, h, w = frames.shape[:3]
    for step in (-1, 1):
        carried = points.reshape(-1, 1, 2).astype(np.float64)
        for j in range(key + step, n if step > 0 else -1, step):
            homography = camera_motion(frames[j - step], frames[j], hands_of(j - step))
            if homography is None:
                break
            carried = cv2.perspectiveTransform(carried, homography)
            if not ((carried >= 0) & (carried < [w, h])).all():
                break
            if _distance_to(hands_of(j), carried.reshape(-1, 2)) > reach:
                return j, carried.reshape(-1, 2)
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


def camera_motion(before: np.ndarray, after: np.ndarray, hands: np.ndarray) -> np.ndarray | None:
    """(3, 3) homography from (H, W, 3) uint8 RGB frame ``before``'s pixels to the next frame ``after``'s,
    fitted (RANSAC) to corners off ``before``'s ``hands`` (H, W) bool tracked with
    Lucas-Kanade; None where fewer than :data:`MIN_CAMERA_INLIERS` agree."""
    before, after = (cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY) for frame in (before, after))
    corners = CAMERA_CORNERS.find(before, _off(hands))
    if corners is None or len(corners) < MIN_CAMERA_INLIERS:
        return None
    source, target = carried_corners(before, after, corners)
    if len(source) < MIN_CAMERA_INLIERS:
        return None
    homography, inliers = cv2.findHomography(source, target, cv2.RANSAC, CAMERA_RANSAC_PX)
    if homography is None or inliers is None or int(inliers.sum()) < MIN_CAMERA_INLIERS:
        return None
    return homography
