"""A hand MediaPipe misses (cut by the border, blurred, a finger alone), found by colour and motion.

:func:`hand_regions` looks, in the frames without a landmark hand, for skin-coloured pixels
that moved against the clip's background and come in from the image's border (the arm
comes from outside the view). NumPy and OpenCV only.
"""

from __future__ import annotations

import cv2
import numpy as np

from warpskill.data.footage.hand_landmarks import MIN_FOLLOW_CORNERS, MIN_HAND_FRACTION, HandTracks, check_frames
from warpskill.data.footage.tracking import CAMERA_CORNERS, CAMERA_RANSAC_PX, carried_corners

SKIN_CR = (133, 173)
"""Range of the red chroma Cr (ITU-R BT.601 YCrCb, 8 bit) of skin, any ethnicity: Chai &
Ngan, "Face segmentation using skin-color map in videophone applications", IEEE TCSVT 9(4),
1999. Applied after grey-world white balance (:data:`SKIN_CB`)."""

SKIN_CB = (77, 127)
"""Range of the blue chroma Cb of skin (Chai & Ngan 1999, see :data:`SKIN_CR`). The frames
are white-balanced first by the grey-world assumption (Buchsbaum 1980: the clip's mean
colour is grey), so a hand under a bluish or greenish light still falls in the ranges (in
the team's two dim real clips 36 % and 29 % of the boxed hands' pixels, against 16 % and 6 %
without it), and a skin-toned scene (a pink bedspread, a wooden desk) mostly leaves them."""

REGION_SCALE = 2
"""Hand regions (:func:`hand_regions`) are found on frames shrunk by this factor per side
(a 427 x 240 clip at 213 x 120) and enlarged back: the hand's box is kept, the cost quartered."""

MOTION_THRESHOLD = 25
"""Smallest change [8-bit levels, largest over R, G, B] of a pixel against the clip's
background (its median over time, the camera's motion compensated) taken as something moving
in front of it: 10 % of the range, above JPEG noise and the background's blur after
registration. On the team's real clips 20 and 30 moved the hand-box share by +1 and -1
points, 20 with 7 more hand-free frames given a hand."""

MIN_REGION_FRACTION = 0.02
"""Smallest hand region, as a fraction of the frame's area: a hand of the smallest size people
boxed in the team's real clips (a palm 0.16 of the shorter side broad, the hand ~2.2 times
as long as broad, about 60 % of its box filled) covers ~0.02 of a 16:9 frame."""

MIN_BACKGROUND_SHARE = 0.25
"""A background pixel (the median over time of the frames registered to one another) counts
only where at least this fraction of the clip's frames sees it; elsewhere the median of a
few frames may be the hand itself, and nothing there is taken as moving."""


def hand_regions(frames: np.ndarray, tracks: HandTracks) -> np.ndarray:
    """The hand where no landmark hand is (neither detected nor followed): skin-coloured
    pixels that moved against the clip's background, their largest blob touching the image's
    border (the arm comes in from outside the view).

    Skin is the generic ranges of :data:`SKIN_CR` and :data:`SKIN_CB` after grey-world white
    balance (a skin model learned from the clip's own detected hands did no better on the
    team's real clips and gave two more false frames).
    Moved is a change of more than :data:`MOTION_THRESHOLD` from the background, the median
    over time of the frames registered to one another by homographies fitted to corners
    tracked between consecutive frames, so a handheld, moving camera's scene does not count
    as moving. Skin-and-moved pixels are closed over gaps as wide as the smallest hand
    (:data:`MIN_HAND_FRACTION` of the shorter side); the largest blob that touches the border
    and covers at least :data:`MIN_REGION_FRACTION` of the frame is the hand with the part of
    the forearm in view. Work is done at 1 / :data:`REGION_SCALE` of the size.

    Args:
        frames: (N, H, W, 3) uint8 RGB frames of one clip, in time order.
        tracks: :func:`find_hands`' hands of these frames.

    Returns:
        (N, H, W) bool; empty in frames where the tracks have a hand or no blob qualifies.

    Raises:
        ValueError: frames not (N, H, W, 3) uint8, or not the tracks' frames.
    """
    frames = check_frames(frames)
    n, h, w = frames.shape[:3]
    if tracks.landmarks.shape[0] != n or tuple(tracks.image_size) != (h, w):
        raise ValueError(f"tracks: expected {n} frames of {(h, w)}, got {tracks.landmarks.shape[0]} of {tracks.image_size}")
    out = np.zeros((n, h, w), dtype=bool)
    todo = np.flatnonzero(~tracks.present().any(axis=1))
    if not len(todo):
        return out
    hs, ws = max(1, h // REGION_SCALE), max(1, w // REGION_SCALE)
    small = np.stack([cv2.resize(frame, (ws, hs), interpolation=cv2.INTER_AREA) for frame in frames])
    skin = _skin(small)
    background, seen = _background(small)
    moved = (np.abs(small.astype(np.int16) - background).max(axis=-1) > MOTION_THRESHOLD) & seen
    width = max(1, int(round(MIN_HAND_FRACTION * min(hs, ws))))
    close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (width, width))
    speck = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    for k in todo:
        candidate = cv2.morphologyEx((skin[k] & moved[k]).astype(np.uint8), cv2.MORPH_OPEN, speck)
        candidate = cv2.morphologyEx(candidate, cv2.MORPH_CLOSE, close)
        count, labels, stats, _ = cv2.connectedComponentsWithStats(candidate, connectivity=8)
        x, y, bw, bh, area = stats[1:].T
        border = (x == 0) | (y == 0) | (x + bw == ws) | (y + bh == hs)
        keep = np.flatnonzero(border & (area >= MIN_REGION_FRACTION * hs * ws))
        if len(keep):
            blob = (labels == 1 + keep[np.argmax(area[keep])]).astype(np.uint8)
            out[k] = cv2.resize(blob, (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)
    return out


def _skin(small: np.ndarray) -> np.ndarray:
    """(N, h, w) bool skin-coloured pixels of the shrunk frames ``small`` (N, h, w, 3) uint8
    RGB: the ranges of :data:`SKIN_CR` and :data:`SKIN_CB` after grey-world white balance."""
    mean = small.reshape(-1, 3).mean(axis=0)
    balanced = np.clip(small * (mean.mean() / np.maximum(mean, 1.0)), 0, 255).astype(np.uint8)
    ycc = np.stack([cv2.cvtColor(frame, cv2.COLOR_RGB2YCrCb) for frame in balanced])
    cr, cb = ycc[..., 1], ycc[..., 2]
    return (cr >= SKIN_CR[0]) & (cr <= SKIN_CR[1]) & (cb >= SKIN_CB[0]) & (cb <= SKIN_CB[1])


def _background(small: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The background behind each shrunk frame and where it is known.

    Every frame is registered to the middle one (homographies chained from one frame to the
    next, :func:`_camera_step`) on a canvas twice the frame's size, the median over time taken
    there (frames not seeing a pixel fill it alternately with black and white, which leaves
    the median of those seeing it about unchanged), and mapped back into each frame.

    Args:
        small: (N, h, w, 3) uint8 RGB.

    Returns:
        (N, h, w, 3) int16 background and (N, h, w) bool, pixels whose background at least
        :data:`MIN_BACKGROUND_SHARE` of the frames see.
    """
    n, hs, ws = small.shape[:3]
    grays = [cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY) for frame in small]
    to_first = [np.eye(3)]
    for k in range(n - 1):
        to_first.append(to_first[-1] @ _camera_step(grays[k], grays[k + 1]))
    shift = np.array([[1.0, 0.0, ws / 2], [0.0, 1.0, hs / 2], [0.0, 0.0, 1.0]]) @ np.linalg.inv(to_first[n // 2])
    to_canvas = [shift @ transform for transform in to_first]
    size = (2 * ws, 2 * hs)
    stack = np.empty((n, 2 * hs, 2 * ws, 3), dtype=np.uint8)
    count = np.zeros((2 * hs, 2 * ws), dtype=np.int32)
    ones = np.ones((hs, ws), dtype=np.uint8)
    for k in range(n):
        fill = (255,) * 3 if k % 2 else (0,) * 3
        stack[k] = cv2.warpPerspective(small[k], to_canvas[k], size, flags=cv2.INTER_LINEAR, borderValue=fill)
        count += cv2.warpPerspective(ones, to_canvas[k], size, flags=cv2.INTER_NEAREST)
    median = np.median(stack, axis=0).astype(np.uint8)
    known = (count >= max(1.0, MIN_BACKGROUND_SHARE * n)).astype(np.uint8)
    back = np.empty_like(small, dtype=np.int16)
    seen = np.empty((n, hs, ws), dtype=bool)
    for k in range(n):
        to_frame = np.linalg.inv(to_canvas[k])
        back[k] = cv2.warpPerspective(median, to_frame, (ws, hs), flags=cv2.INTER_LINEAR)
        seen[k] = cv2.warpPerspective(known, to_frame, (ws, hs), flags=cv2.INTER_NEAREST) > 0
    return back, seen


def _camera_step(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """(3, 3) homography from frame ``after``'s pixels to ``before``'s, fitted (RANSAC) to
    corners tracked with Lucas-Kanade (kept where tracking back returns to the start); the
    identity when fewer than :data:`MIN_FOLLOW_CORNERS` corners agree."""
    corners = CAMERA_CORNERS.find(before)
    if corners is None or len(corners) < MIN_FOLLOW_CORNERS:
        return np.eye(3)
    source, target = carried_corners(before, after, corners)
    if len(source) < MIN_FOLLOW_CORNERS:
        return np.eye(3)
    homography, inliers = cv2.findHomography(target, source, cv2.RANSAC, CAMERA_RANSAC_PX)
    if homography is None or inliers is None or int(inliers.sum()) < MIN_FOLLOW_CORNERS:
        return np.eye(3)
    return homography
