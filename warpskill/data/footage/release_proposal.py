"""What the hand brought to where it releases the object, for the outline's proposal.

At the release the object touches the static object it is set onto, beside or in front of,
and a cut-out by colour (GrabCut against the table) may take both as one piece. The object
came with the hand; the static object was there before. :func:`stayed` marks the pixels of
the release frame that show what an earlier frame showed at the same place (the camera's
motion fitted frame to frame, :func:`.unhidden_proposal.camera_motion`), taken from a frame
where the hand was far enough away for the object to have been elsewhere
(:func:`earlier_elsewhere`). OpenCV and NumPy only.
"""

from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

from warpskill.data.footage.unhidden_proposal import camera_motion

STAY_LEVELS = 20.0
"""Largest mean colour difference [8-bit levels, both frames blurred over :data:`BLUR_PX`]
of a pixel that shows the same as before (compression noise and a slightly wrong camera
motion stay below it; an object against its support differs by more)."""

BLUR_PX = 5
"""Side [px] of the Gaussian blur both frames are compared after (a pixel's neighbourhood,
so that a sub-pixel error of the camera's motion does not count as a change)."""


def earlier_elsewhere(grips: np.ndarray, key: int, extent: float) -> int | None:
    """The latest frame before ``key`` whose grip (N, 2) [px] lies at least ``extent`` [px]
    (the object's size) from the key frame's: the object it carried lay elsewhere then; None
    where there is none."""
    for j in range(key - 1, -1, -1):
        if np.isfinite(grips[j]).all() and np.linalg.norm(grips[j] - grips[key]) >= extent:
            return j
    return None


def stayed(frames: np.ndarray, key: int, earlier: int, hands_of: Callable[[int], np.ndarray]) -> np.ndarray | None:
    """(H, W) bool: the pixels of frame ``key`` that show what frame ``earlier`` showed there
    (within :data:`STAY_LEVELS`), off the hands of frame ``earlier``; None where the camera's
    motion is not fitted between some two frames in between.

    Args:
        frames: (N, H, W, 3) uint8 RGB frames.
        key, earlier: two frames, ``earlier`` < ``key``.
        hands_of: frame index -> (H, W) bool, every hand seen in it.
    """
    h, w = frames.shape[1:3]
    to_earlier = np.eye(3)
    for j in range(key, earlier, -1):
        step = camera_motion(frames[j], frames[j - 1], hands_of(j))
        if step is None:
            return None
        to_earlier = step @ to_earlier
    flags = cv2.WARP_INVERSE_MAP
    before = cv2.warpPerspective(frames[earlier], to_earlier, (w, h), flags=cv2.INTER_LINEAR | flags)
    seen = cv2.warpPerspective(np.ones((h, w), np.uint8), to_earlier, (w, h), flags=cv2.INTER_NEAREST | flags) > 0
    hidden = cv2.warpPerspective(hands_of(earlier).astype(np.uint8), to_earlier, (w, h),
                                 flags=cv2.INTER_NEAREST | flags) > 0
    now, then = (cv2.GaussianBlur(image, (BLUR_PX, BLUR_PX), 0).astype(np.float32) for image in (frames[key], before))
    return (np.abs(now - then).mean(axis=2) < STAY_LEVELS) & seen & ~hidden
