"""Contact estimation: per-frame hand-object contact from detections or masks, then the
paper's three-step filter.

Raw detections are per-frame states: :data:`IN_CONTACT`, :data:`NO_CONTACT` (the hand is
seen and does not touch the object: a *negative* detection) or :data:`UNKNOWN` (no
detection: the hand is not visible, or the detector is not confident). The filter
(:func:`filter_contact`) turns them into a boolean contact signal:

(a) majority smoothing (5-frame window, 3 votes) of the positive detections;
(b) if the object moves at the start of the video (its mask centroid shifts by more than
    ``moving_px`` over its first visible frames), the hand holds it from frame 0 until the
    first negative detection; likewise at the end;
(c) the last release moves earlier, to where the object's mask stops moving.

Frames still unknown afterwards are in contact only when contact frames flank them (the
hand briefly unseen while holding), otherwise not.

Detections come from a detector's file (:func:`warpskill.data.readers.contact_files.read_detections`),
from the hand's landmarks (:func:`warpskill.data.footage.touch.detections_from_landmarks`) or
from the masks alone (:func:`detections_from_masks`). Every pipeline of :mod:`warpskill.data`
shares this module.
"""

from __future__ import annotations

import cv2
import numpy as np

from warpskill.contract.signals import majority_filter

IN_CONTACT, NO_CONTACT, UNKNOWN = 1, 0, -1

MOVING_PX = 4.0
"""Centroid shift [px at the mask resolution] over the first (last) visible frames that counts as moving."""

STILL_PX = 1.5
"""Centroid motion per frame [px] below which the object counts as still (step (c))."""

SPAN = 3
"""Visible frames at each end of the video over which step (b) measures the object's shift."""


def detections_from_masks(
    hand_mask: np.ndarray, object_mask: np.ndarray, *, touch_px: int = 2, moving_px: float = MOVING_PX
) -> np.ndarray:
    """Contact detections from masks alone, for videos without a contact detector.

    A frame is :data:`IN_CONTACT` when the hand mask, grown by ``touch_px``, touches or
    overlaps the object mask, or when the hand is visible and the object's centroid moved
    by more than ``moving_px`` since the previous frame (objects do not move by
    themselves); :data:`NO_CONTACT` when both are visible otherwise; :data:`UNKNOWN` when
    the hand or the object is not visible. A 2D touch is only evidence: a hand passing
    in front of the object touches it in the image too.

    Args:
        hand_mask: (N, H, W) bool.
        object_mask: (N, H, W) bool.
        touch_px: growth of the hand mask [px].
        moving_px: per-frame centroid motion [px] that counts as the object moving.

    Returns:
        (N,) int8 in {UNKNOWN, NO_CONTACT, IN_CONTACT}.
    """
    hand_mask, object_mask = np.asarray(hand_mask, dtype=bool), np.asarray(object_mask, dtype=bool)
    if hand_mask.ndim != 3 or hand_mask.shape != object_mask.shape:
        raise ValueError(f"hand_mask {hand_mask.shape} and object_mask {object_mask.shape}: expected equal (N, H, W)")
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * touch_px + 1, 2 * touch_px + 1))
    moved = np.nan_to_num(centroid_motion(object_mask)) > moving_px
    detections = np.full(len(hand_mask), UNKNOWN, dtype=np.int8)
    for k, (hand, obj) in enumerate(zip(hand_mask, object_mask)):
        if not (hand.any() and obj.any()):
            continue
        grown = cv2.dilate(hand.astype(np.uint8), kernel).astype(bool)
        detections[k] = IN_CONTACT if (grown & obj).any() or moved[k] else NO_CONTACT
    return detections


def centroid_motion(masks: np.ndarray) -> np.ndarray:
    """Per-frame motion of a mask's centroid.

    Args:
        masks: (N, H, W) bool.

    Returns:
        (N,) float [px]: ``|c[k] - c[k - 1]|``; NaN at frame 0 and where the mask is empty
        in frame k or k - 1.
    """
    centroids = _centroids(masks)
    motion = np.full(len(centroids), np.nan)
    motion[1:] = np.linalg.norm(np.diff(centroids, axis=0), axis=1)
    return motion


def smooth_detections(detections: np.ndarray, window: int = 5) -> np.ndarray:
    """Step (a): majority vote of the positive detections (:func:`majority_filter`).

    Frames the vote turns positive become :data:`IN_CONTACT`; positives it removes become
    :data:`NO_CONTACT`; other frames keep their state.

    Args:
        detections: (N,) int in {UNKNOWN, NO_CONTACT, IN_CONTACT}.
        window: frames per vote.

    Returns:
        (N,) int8 in {UNKNOWN, NO_CONTACT, IN_CONTACT}.
    """
    detections = _check_detections(detections)
    positive = majority_filter(detections == IN_CONTACT, window)
    smoothed = detections.copy()
    smoothed[positive] = IN_CONTACT
    smoothed[~positive & (detections == IN_CONTACT)] = NO_CONTACT
    return smoothed


def extend_to_ends(detections: np.ndarray, object_mask: np.ndarray, *, moving_px: float = MOVING_PX) -> np.ndarray:
    """Step (b): an object moving at the start is held from frame 0 until the first
    negative detection; one moving at the end is held from after the last negative
    detection to the last frame.

    Args:
        detections: (N,) int in {UNKNOWN, NO_CONTACT, IN_CONTACT}.
        object_mask: (N, H, W) bool.
        moving_px: centroid shift [px] over the first (last) :data:`SPAN` visible frames
            above which the object counts as moving.

    Returns:
        (N,) int8: ``detections`` with the held frames set to :data:`IN_CONTACT`.
    """
    detections = _check_detections(detections)
    centroids = _centroids(object_mask)
    visible = np.flatnonzero(~np.isnan(centroids[:, 0]))
    extended = detections.copy()
    if len(visible) < 2:
        return extended
    negatives = np.flatnonzero(detections == NO_CONTACT)
    first, last = visible[:SPAN], visible[-SPAN:]
    if np.linalg.norm(centroids[first[-1]] - centroids[first[0]]) > moving_px:
        extended[: negatives[0] if len(negatives) else len(extended)] = IN_CONTACT
    if np.linalg.norm(centroids[last[-1]] - centroids[last[0]]) > moving_px:
        extended[negatives[-1] + 1 if len(negatives) else 0 :] = IN_CONTACT
    return extended


def advance_release(
    contact: np.ndarray, object_mask: np.ndarray, *, still_px: float = STILL_PX, margin: int = 1
) -> np.ndarray:
    """Step (c): end the last contact run ``margin`` frames after the object's mask stops
    moving, when the run ends inside the video (a release is seen) and the object moved
    during it. Contact detectors tend to report contact while the hand is still near.

    Motion is the majority-filtered (:func:`majority_filter`) per-frame centroid motion
    above ``still_px``.

    Args:
        contact: (N,) bool.
        object_mask: (N, H, W) bool.
        still_px: per-frame centroid motion [px] at or below which the object is still.
        margin: frames of contact kept after the last moving frame.

    Returns:
        (N,) bool.
    """
    contact = np.asarray(contact, dtype=bool).copy()
    on = np.flatnonzero(contact)
    if not len(on) or on[-1] == len(contact) - 1:
        return contact
    end = on[-1]
    off_before = np.flatnonzero(~contact[:end])
    start = off_before[-1] + 1 if len(off_before) else 0
    moving = majority_filter(np.nan_to_num(centroid_motion(object_mask)) > still_px)
    moved = np.flatnonzero(moving[start : end + 1])
    if len(moved):
        contact[start + moved[-1] + margin + 1 : end + 1] = False
    return contact


def filter_contact(
    detections: np.ndarray,
    object_mask: np.ndarray,
    *,
    window: int = 5,
    moving_px: float = MOVING_PX,
    still_px: float = STILL_PX,
) -> np.ndarray:
    """The paper's filter: (a) :func:`smooth_detections`, (b) :func:`extend_to_ends`, then
    unknown frames flanked by contact become contact, other unknown frames not, and (c)
    :func:`advance_release`.

    Args:
        detections: (N,) int in {UNKNOWN, NO_CONTACT, IN_CONTACT}.
        object_mask: (N, H, W) bool.
        window: frames per majority vote in (a).
        moving_px: see :func:`extend_to_ends`.
        still_px: see :func:`advance_release`.

    Returns:
        (N,) bool contact signal.
    """
    states = extend_to_ends(smooth_detections(detections, window), object_mask, moving_px=moving_px)
    on = np.flatnonzero(states == IN_CONTACT)
    contact = states == IN_CONTACT
    if len(on):
        span = slice(on[0], on[-1] + 1)
        contact[span] |= states[span] == UNKNOWN
    return advance_release(contact, object_mask, still_px=still_px)


def estimate_contact(
    hand_mask: np.ndarray, object_mask: np.ndarray, *, detections: np.ndarray | None = None
) -> np.ndarray:
    """Contact signal of a video: ``detections`` (e.g. from :func:`~warpskill.data.readers.contact_files.read_detections`) or,
    lacking them, :func:`detections_from_masks`, through :func:`filter_contact`.

    Args:
        hand_mask: (N, H, W) bool.
        object_mask: (N, H, W) bool.
        detections: (N,) int in {UNKNOWN, NO_CONTACT, IN_CONTACT}, or None.

    Returns:
        (N,) bool.
    """
    if detections is None:
        detections = detections_from_masks(hand_mask, object_mask)
    return filter_contact(detections, object_mask)


def _centroids(masks: np.ndarray) -> np.ndarray:
    """(N, H, W) bool -> (N, 2) float centroids (x, y) [px]; NaN rows for empty frames."""
    masks = np.asarray(masks, dtype=bool)
    if masks.ndim != 3:
        raise ValueError(f"object_mask: expected shape (N, H, W), got {masks.shape}")
    area = masks.sum(axis=(1, 2)).astype(float)
    ys, xs = np.arange(masks.shape[1]) + 0.5, np.arange(masks.shape[2]) + 0.5
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = (masks.sum(axis=1) * xs).sum(axis=1) / area
        cy = (masks.sum(axis=2) * ys).sum(axis=1) / area
    return np.stack([cx, cy], axis=1)


def _check_detections(detections: np.ndarray) -> np.ndarray:
    """``detections`` as (N,) int8; raises ValueError for other shapes or values."""
    detections = np.asarray(detections)
    if detections.ndim != 1 or detections.dtype.kind not in "iu":
        raise ValueError(f"detections: expected a (N,) integer array, got {detections.dtype} of shape {detections.shape}")
    bad = ~np.isin(detections, (UNKNOWN, NO_CONTACT, IN_CONTACT))
    if bad.any():
        raise ValueError(f"detections: expected values in {{-1, 0, 1}}, found {detections[bad][0]}")
    return detections.astype(np.int8)
