"""Contact detections read off the hand's landmarks: a fingertip on or at the object.

:func:`detections_from_landmarks` gives the raw per-frame detections of the footage path
(:mod:`.clip_masks`), which go through the paper's filter
(:func:`warpskill.data.contact.filter_contact`) as a detector's would.
"""

from __future__ import annotations

import cv2
import numpy as np

from warpskill.data.contact import IN_CONTACT, NO_CONTACT, UNKNOWN
from warpskill.data.footage.hand_landmarks import FINGERTIPS, INDEX_KNUCKLE, PINKY_KNUCKLE

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
