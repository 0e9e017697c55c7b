"""One hand per frame, and its mask: from the landmarks of :mod:`warpskill.data.footage.hand_landmarks`.

:func:`choose_hand` keeps one hand per frame (the one touching the object, else the one
continuing the previous frame's, else the most confident); :func:`hand_masks` turns
landmarks into a mask (the landmarks' convex hull widened to the hand's thickness, plus the
forearm); :func:`hand_measurements` gives the palm's breadth and the hand's length in pixels.
:func:`warpskill.data.footage.clip_masks.footage_masks` chains them with
:func:`~warpskill.data.footage.hand_landmarks.find_hands` and, where no landmark hand is,
:func:`~warpskill.data.footage.hand_regions.hand_regions`. NumPy and OpenCV only.
"""

from __future__ import annotations

import cv2
import numpy as np

from warpskill.data.footage.hand_landmarks import (
    HAND_LANDMARKS,
    INDEX_KNUCKLE,
    MIDDLE_FINGER,
    MIDDLE_KNUCKLE,
    PINKY_KNUCKLE,
    SAME_HAND_FRACTION,
    WIDEN_FRACTION,
    WRIST,
    HandTracks,
    hand_size,
    hull_mask,
)

NEARER_FRACTION = 0.25
"""Where several hands are seen, the hand nearest the object's mask is the one that handles
it when the next hand is farther by more than this fraction of the hand's size; closer
calls are left to the continuity with the previous frames."""

WRIST_WIDTH_FRACTION = 0.7
"""The forearm band's width, as a fraction of the hand's size (wrist ~6 cm against a palm
~8.5 cm)."""

FOREARM_REACH = 1.5
"""The forearm is drawn to the image border when the border is within this many hand
lengths of the wrist along the forearm's direction (a forearm is ~1.4 hand lengths);
otherwise a stub of one hand length is drawn."""


def _check_landmarks(landmarks: np.ndarray) -> np.ndarray:
    """(N, 21, 2) float landmarks, or ValueError."""
    landmarks = np.asarray(landmarks, dtype=float)
    if landmarks.ndim != 3 or landmarks.shape[1:] != (HAND_LANDMARKS, 2):
        raise ValueError(f"landmarks: expected (N, {HAND_LANDMARKS}, 2), got {landmarks.shape}")
    return landmarks


def _has_hand(landmarks: np.ndarray) -> np.ndarray:
    """(N,) bool: frames whose landmarks are all finite."""
    return np.isfinite(landmarks).all(axis=(1, 2))


def choose_hand(tracks: HandTracks, object_masks: np.ndarray | None = None) -> np.ndarray:
    """One hand per frame: where several are seen, the one nearest to the object's mask (if
    given and non-empty in that frame and the hands' distances to it differ), else the one
    continuing the hand chosen in the previous frames, else the most confident (a detected
    hand before a followed one).

    Args:
        tracks: :func:`find_hands`' hands.
        object_masks: (N, H, W) bool masks of the manipulated object, or None.

    Returns:
        (N, 21, 2) landmarks (x, y) [px]; NaN rows in frames without a hand.

    Raises:
        ValueError: ``object_masks`` not (N, H, W) as the tracks.
    """
    n = tracks.landmarks.shape[0]
    if object_masks is not None:
        object_masks = np.asarray(object_masks, dtype=bool)
        if object_masks.shape != (n, *tracks.image_size):
            raise ValueError(f"object_masks: expected {(n, *tracks.image_size)}, got {object_masks.shape}")
    present = tracks.present()
    out = np.full((n, HAND_LANDMARKS, 2), np.nan)
    previous = None  # the last chosen hand's landmarks
    for k in range(n):
        slots = np.flatnonzero(present[k])
        if not len(slots):
            continue
        if len(slots) > 1:
            slot = _pick(tracks, k, slots, None if object_masks is None else object_masks[k], previous)
        else:
            slot = slots[0]
        out[k] = tracks.landmarks[k, slot]
        previous = out[k]
    return out


def _pick(tracks: HandTracks, k: int, slots: np.ndarray, mask: np.ndarray | None, previous: np.ndarray | None) -> int:
    """The slot of frame ``k`` to keep among several hands (see :func:`choose_hand`)."""
    hands = tracks.landmarks[k, slots]
    sizes = hand_size(hands)
    if mask is not None and mask.any():
        distance = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 3)
        h, w = mask.shape
        gaps = []
        for points in hands:
            xy = np.round(points).astype(int)
            inside = (xy[:, 0] >= 0) & (xy[:, 0] < w) & (xy[:, 1] >= 0) & (xy[:, 1] < h)
            gaps.append(distance[xy[inside, 1], xy[inside, 0]].min() if inside.any() else np.inf)
        gaps = np.array(gaps)
        order = np.argsort(gaps)
        if gaps[order[1]] - gaps[order[0]] > NEARER_FRACTION * float(np.nanmedian(sizes)):
            return int(slots[order[0]])
    if previous is not None:
        shift = np.linalg.norm(hands.mean(axis=1) - previous.mean(axis=0), axis=-1)
        order = np.argsort(shift)
        if shift[order[0]] < SAME_HAND_FRACTION * float(hand_size(previous)):
            return int(slots[order[0]])
    followed = tracks.followed[k, slots]
    scores = np.nan_to_num(tracks.scores[k, slots])
    return int(slots[np.lexsort((-scores, followed))[0]])


def hand_masks(landmarks: np.ndarray, image_size: tuple[int, int], *, forearm: bool = True) -> np.ndarray:
    """Hand masks from landmarks: the landmarks' convex hull widened by
    :data:`WIDEN_FRACTION` of the hand's size (palm breadth, :func:`hand_measurements`) to
    cover the fingers' and the wrist's flesh; with ``forearm`` also a band
    :data:`WRIST_WIDTH_FRACTION` of the hand's size wide from the wrist away from the
    fingers (middle knuckle -> wrist), to the image border when the border is within
    :data:`FOREARM_REACH` hand lengths, else one hand length long.

    Args:
        landmarks: (N, 21, 2) landmarks (x, y) [px]; frames with any NaN have no hand.
        image_size: (H, W) [px].
        forearm: draw the forearm.

    Returns:
        (N, H, W) bool; empty in frames without a hand.

    Raises:
        ValueError: landmarks not (N, 21, 2) or a non-positive image size.
    """
    landmarks = _check_landmarks(landmarks)
    h, w = (int(v) for v in image_size)
    if h <= 0 or w <= 0:
        raise ValueError(f"image_size: expected (H, W) > 0, got {image_size}")
    out = np.zeros((len(landmarks), h, w), dtype=bool)
    sizes = hand_size(landmarks)
    lengths = hand_measurements(landmarks)[:, 1]
    for k in np.flatnonzero(_has_hand(landmarks)):
        points, size = landmarks[k], float(sizes[k])
        mask = hull_mask(points, (h, w), WIDEN_FRACTION * size)
        if forearm:
            mask |= _forearm(points, (h, w), size, float(lengths[k]))
        out[k] = mask
    return out


def _forearm(points: np.ndarray, image_size: tuple[int, int], size: float, length: float) -> np.ndarray:
    """(H, W) bool: the forearm band from the wrist (see :func:`hand_masks`)."""
    h, w = image_size
    wrist = points[WRIST]
    axis = wrist - points[MIDDLE_KNUCKLE]
    norm = float(np.linalg.norm(axis))
    canvas = np.zeros((h, w), dtype=np.uint8)
    if norm < 1e-6 or not np.isfinite(length) or length <= 0:
        return canvas.astype(bool)
    axis /= norm
    # distance along the axis from the wrist to the image's border (inf when parallel)
    with np.errstate(divide="ignore", invalid="ignore"):
        bounds = np.array([(0.0 - wrist[0]) / axis[0], (w - wrist[0]) / axis[0], (0.0 - wrist[1]) / axis[1], (h - wrist[1]) / axis[1]])
    to_border = float(np.min(bounds[np.isfinite(bounds) & (bounds >= 0)], initial=np.inf))
    reach = to_border + size if to_border <= FOREARM_REACH * length else length
    end = wrist + axis * reach
    shift = 4
    thickness = max(1, int(round(WRIST_WIDTH_FRACTION * size)))
    start_px = tuple(int(v) for v in np.round(wrist * (1 << shift)))
    end_px = tuple(int(v) for v in np.round(end * (1 << shift)))
    cv2.line(canvas, start_px, end_px, 1, thickness=thickness, lineType=cv2.LINE_8, shift=shift)
    return canvas.astype(bool)


def hand_measurements(landmarks: np.ndarray) -> np.ndarray:
    """The hand's apparent palm breadth and length per frame, a ruler for the scene's scale
    (an adult's palm is ~8.5 cm broad, the hand ~19 cm long).

    Args:
        landmarks: (N, 21, 2) landmarks (x, y) [px].

    Returns:
        (N, 2) [px]: palm breadth (index to little finger knuckle) and hand length (wrist to
        middle knuckle plus the middle finger's three segments, so a bent finger keeps its
        length); NaN rows in frames without a hand. Both shrink when the hand is seen
        edge-on or end-on (foreshortening).

    Raises:
        ValueError: landmarks not (N, 21, 2).
    """
    landmarks = _check_landmarks(landmarks)
    breadth = np.linalg.norm(landmarks[:, INDEX_KNUCKLE] - landmarks[:, PINKY_KNUCKLE], axis=-1)
    chain = landmarks[:, (WRIST, *MIDDLE_FINGER)]
    length = np.linalg.norm(np.diff(chain, axis=1), axis=-1).sum(axis=1)
    out = np.stack([breadth, length], axis=1)
    out[~_has_hand(landmarks)] = np.nan
    return out
