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
"""

from __future__ import annotations

import csv
import math
import os

import cv2
import numpy as np

from warpskill.contract.demonstration import DemonstrationError
from warpskill.contract.signals import majority_filter
from warpskill.data.hand_landmarks import FINGERTIPS, INDEX_KNUCKLE, PINKY_KNUCKLE

IN_CONTACT, NO_CONTACT, UNKNOWN = 1, 0, -1

MOVING_PX = 4.0
"""Centroid shift [px at the mask resolution] over the first (last) visible frames that counts as moving."""

STILL_PX = 1.5
"""Centroid motion per frame [px] below which the object counts as still (step (c))."""

SPAN = 3
"""Visible frames at each end of the video over which step (b) measures the object's shift."""


def read_detections(path: str | os.PathLike, num_frames: int, *, min_score: float = 0.5) -> np.ndarray:
    """Read a hand-object contact detections CSV.

    The file has a header row with the columns ``frame`` (0-based index into the masks),
    ``in_contact`` (0/1, or true/false) and optionally ``score`` (the detector's confidence
    in [0, 1]). A frame absent from the file, or detected with ``score < min_score``, is
    :data:`UNKNOWN`.

    Args:
        path: the CSV file.
        num_frames: N, the number of frames of the masks.
        min_score: detections below this score count as no detection.

    Returns:
        (N,) int8 in {UNKNOWN, NO_CONTACT, IN_CONTACT}.

    Raises:
        DemonstrationError: (a ValueError) naming the file and line, for text that is not
            UTF-8 CSV, a missing column, a frame out of range or repeated, or a value that is
            not a number / boolean (a score that is not finite).
        FileNotFoundError: ``path`` does not exist.
    """
    detections = np.full(num_frames, UNKNOWN, dtype=np.int8)
    seen = set()
    with open(path, newline="", encoding="utf-8-sig") as handle:
        reader = csv.DictReader(handle)
        try:
            missing = {"frame", "in_contact"} - set(reader.fieldnames or ())
            if missing:
                raise DemonstrationError(
                    f"{path}: missing column(s) {', '.join(sorted(missing))}; expected frame,in_contact[,score]"
                )
            for row in reader:
                where = f"{path}, line {reader.line_num}"
                frame = _parse(where, "frame", row["frame"], int)
                if not 0 <= frame < num_frames:
                    raise DemonstrationError(f"{where}: frame {frame} outside 0..{num_frames - 1}")
                if frame in seen:
                    raise DemonstrationError(f"{where}: frame {frame} listed twice")
                seen.add(frame)
                if row.get("score") not in (None, ""):
                    score = _parse(where, "score", row["score"], float)
                    if not math.isfinite(score):
                        raise DemonstrationError(f"{where}: column score: expected a finite number, got {row['score']!r}")
                    if score < min_score:
                        continue
                detections[frame] = IN_CONTACT if _parse(where, "in_contact", row["in_contact"], _boolean) else NO_CONTACT
        except UnicodeDecodeError as exc:
            raise DemonstrationError(f"{path}: not UTF-8 text ({exc})") from None
        except csv.Error as exc:
            raise DemonstrationError(f"{path}, line {reader.line_num}: not a readable CSV row ({exc})") from None
    return detections


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


TOUCH_BREADTHS = 0.25
"""A fingertip this close to the object's mask, in palm breadths, touches it (about 2 cm of a
hand, a finger's width: a fingertip resting on the object lies on or just beside its visible
mask, since the finger itself hides the object under it)."""


def detections_from_landmarks(
    landmarks: np.ndarray, object_mask: np.ndarray, *, touch_breadths: float = TOUCH_BREADTHS
) -> np.ndarray:
    """Contact detections from hand landmarks: a fingertip on or at the object's mask.

    A frame is :data:`IN_CONTACT` when a fingertip lies within ``touch_breadths`` palm
    breadths of the object's visible mask, :data:`NO_CONTACT` when the hand and the object
    are seen and no fingertip does, :data:`UNKNOWN` when either is not seen. Filter them
    with :func:`filter_contact`, as the paper filters a detector's output.

    Args:
        landmarks: (N, 21, 2) hand landmarks (x, y) [px], NaN rows where no hand is seen.
        object_mask: (N, H, W) bool.
        touch_breadths: the touching distance [palm breadths].

    Returns:
        (N,) int8 in {UNKNOWN, NO_CONTACT, IN_CONTACT}.
    """
    landmarks, object_mask = np.asarray(landmarks, dtype=float), np.asarray(object_mask, dtype=bool)
    if landmarks.ndim != 3 or landmarks.shape[1:] != (21, 2) or object_mask.ndim != 3 or len(landmarks) != len(object_mask):
        raise ValueError(
            f"landmarks {landmarks.shape} and object_mask {object_mask.shape}: expected (N, 21, 2) and (N, H, W)"
        )
    h, w = object_mask.shape[1:]
    detections = np.full(len(landmarks), UNKNOWN, dtype=np.int8)
    for k, (points, obj) in enumerate(zip(landmarks, object_mask)):
        if not (np.isfinite(points).all() and obj.any()):
            continue
        distance = cv2.distanceTransform((~obj).astype(np.uint8), cv2.DIST_L2, 3)
        tips = np.round(points[list(FINGERTIPS)] - 0.5).astype(int)
        inside = (tips[:, 0] >= 0) & (tips[:, 0] < w) & (tips[:, 1] >= 0) & (tips[:, 1] < h)
        breadth = float(np.linalg.norm(points[INDEX_KNUCKLE] - points[PINKY_KNUCKLE]))
        near = distance[tips[inside, 1], tips[inside, 0]] <= touch_breadths * breadth
        detections[k] = IN_CONTACT if near.any() else NO_CONTACT
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
    """Contact signal of a video: ``detections`` (e.g. from :func:`read_detections`) or,
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


def _boolean(text: str) -> bool:
    """'1'/'0'/'true'/'false' (any case) -> bool."""
    value = text.strip().lower()
    if value in ("1", "true"):
        return True
    if value in ("0", "false"):
        return False
    raise ValueError(text)


def _parse(where: str, column: str, text: str | None, kind):
    """``kind(text)``, or a DemonstrationError naming ``where`` and ``column``."""
    try:
        return kind((text or "").strip())
    except ValueError:
        raise DemonstrationError(f"{where}: column {column}: cannot read {text!r} as {kind.__name__.lstrip('_')}") from None
