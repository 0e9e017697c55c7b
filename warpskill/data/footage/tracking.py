"""Sparse corners carried from one frame to the next, and every setting of it in one place.

The one Lucas-Kanade step (:func:`carried_corners`) that the object follower
(:mod:`.following`), the hand follower (:mod:`.hand_landmarks`) and the camera's motion
(:mod:`.hand_regions`) share, the corners each of them picks (:class:`CornerSearch`), and
the RANSAC thresholds and per-frame scale limits of the motions fitted to them. Where two
users differ, each setting is named for its user and says why. NumPy and OpenCV only.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

LK_WINDOW_PX = 15
"""Side [px] of the Lucas-Kanade window."""

LK_LEVELS = 4
"""Pyramid levels of Lucas-Kanade above the full frame (motions up to ~15 x 2^4 px a frame)."""

ROUND_TRIP_PX = 1.0
"""A corner is kept when tracking it forward then back returns within this [px] of where it started."""


@dataclasses.dataclass(frozen=True)
class CornerSearch:
    """Which corners of a grey frame are tracked (``cv2.goodFeaturesToTrack``).

    Attributes:
        most: most corners.
        quality: least corner response, as a fraction of the strongest corner's.
        spacing_px: least distance [px] between two corners.
        block_px: side [px] of the window the corner response is summed over.
    """

    most: int
    quality: float
    spacing_px: float
    block_px: int = 3

    def find(self, grey: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray | None:
        """(M, 1, 2) float32 corners [px] of the (H, W) uint8 ``grey`` inside ``mask``
        ((H, W) uint8, nonzero where allowed; None: anywhere); None where there are none."""
        return cv2.goodFeaturesToTrack(grey, self.most, self.quality, self.spacing_px, mask=mask,
                                       blockSize=self.block_px)


HAND_CORNERS = CornerSearch(most=60, quality=0.01, spacing_px=3)
"""Corners on one hand (its landmarks' hull): a hand is small and smooth-skinned, so a few
dozen of its strongest corners are all it has."""

OBJECT_CORNERS = CornerSearch(most=150, quality=0.005, spacing_px=3, block_px=5)
"""Corners inside one followed label (or the background): weaker corners too and a wider
window, so that a plain object still gets enough; their motion is one similarity."""

CAMERA_CORNERS = CornerSearch(most=200, quality=0.01, spacing_px=4)
"""Corners over the whole frame for the camera's motion (a homography) from one frame to the next."""

HAND_RANSAC_PX = 2.0
"""RANSAC inlier threshold [px] of the similarity fitted to a hand's corners: looser than an
object's (:data:`OBJECT_RANSAC_PX`), as fingers bend while the hand moves."""

CAMERA_RANSAC_PX = 2.0
"""RANSAC inlier threshold [px] of the camera's homography (the hand's threshold, not tuned apart)."""

OBJECT_RANSAC_PX = 1.5
"""RANSAC inlier threshold [px] of the similarity fitted to a rigid label's corners."""

FLOW_RANSAC_PX = 1.0
"""RANSAC inlier threshold [px] of the similarity fitted to a mask's dense flow
(:mod:`.propagation`): every pixel of the mask votes, so a tight threshold still keeps many."""

HAND_MAX_SCALE_STEP = 0.25
"""Largest relative change of a followed hand's size from one frame to the next; more is a
flow failure, and following stops. Wide, as a hand turning to the camera or opening
changes its corners' spread fast."""

OBJECT_MAX_SCALE_STEP = 0.08
"""Largest relative change of a followed label's scale from one frame to the next; a larger
fitted change is clamped to it (a rigid object's apparent size changes slowly: an object
0.5 m from the camera coming 4 cm nearer in a frame)."""


def carried_corners(before: np.ndarray, after: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corners of grey frame ``before`` and their places in ``after``, tracked with
    pyramidal Lucas-Kanade and kept where tracking back returns to the start.

    Args:
        before, after: (H, W) uint8 grey frames.
        corners: (M, 1, 2) float32 corners [px] in ``before`` (:meth:`CornerSearch.find`'s shape).

    Returns:
        Two (K, 2) float32 arrays [px]: the kept corners and where they went.
    """
    params = dict(winSize=(LK_WINDOW_PX, LK_WINDOW_PX), maxLevel=LK_LEVELS)
    ahead, ok, _ = cv2.calcOpticalFlowPyrLK(before, after, corners, None, **params)
    back, ok_back, _ = cv2.calcOpticalFlowPyrLK(after, before, ahead, None, **params)
    good = (ok[:, 0] == 1) & (ok_back[:, 0] == 1) & (np.linalg.norm(back - corners, axis=2)[:, 0] < ROUND_TRIP_PX)
    return corners[good, 0], ahead[good, 0]
