"""The model hand drawn along a found hand: the hand as a ruler.

The optimiser's hand is a cylinder of known width (:mod:`warpskill.contract.vocabulary`'s
model hand) and reads the scene's scale off the hand mask's apparent width
(``warpskill.optimizer.measurements.hand_depth``). So the hand mask given to it,
:func:`model_hand_masks`, is that cylinder's silhouette drawn along the found hand (from the
fingertips through the wrist and on along the forearm) with the width that the landmarks'
palm breadth measures for an adult hand (:data:`warpskill.nouns.typical.HAND_BREADTH`): the
hand's apparent size in every frame where it is seen becomes the scene's scale.
"""

from __future__ import annotations

import cv2
import numpy as np

from warpskill.contract.vocabulary import MODEL_HAND_LENGTH, MODEL_HAND_RADIUS
from warpskill.data.footage.hand_landmarks import FINGERTIPS, MIDDLE_KNUCKLE, WRIST, hand_size
from warpskill.nouns.typical import HAND_BREADTH


def model_hand_masks(landmarks: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """The model hand drawn along found hands: per frame a band as wide as the model
    cylinder (twice :data:`~warpskill.contract.vocabulary.MODEL_HAND_RADIUS`) at the scale
    the hand's apparent breadth gives
    (:func:`warpskill.data.footage.hand_landmarks.hand_size`, an adult's
    :data:`~warpskill.nouns.typical.HAND_BREADTH`), from the farthest fingertip along the
    hand's axis (middle knuckle to wrist) on for the cylinder's length (at least past the
    wrist), or to the image border.

    Args:
        landmarks: (N, 21, 2) landmarks (x, y) [px], NaN rows where no hand is seen.
        image_size: (H, W) [px].

    Returns:
        (N, H, W) bool; empty in frames without landmarks.
    """
    landmarks = np.asarray(landmarks, dtype=float)
    if landmarks.ndim != 3 or landmarks.shape[1:] != (21, 2):
        raise ValueError(f"landmarks: expected (N, 21, 2), got {landmarks.shape}")
    h, w = image_size
    masks = np.zeros((len(landmarks), h, w), dtype=np.uint8)
    for k, points in enumerate(landmarks):
        if not np.isfinite(points).all():
            continue
        axis = points[WRIST] - points[MIDDLE_KNUCKLE]  # towards the arm
        length = float(np.linalg.norm(axis))
        breadth = float(hand_size(points))
        if length <= 0 or breadth <= 0:
            continue
        axis /= length
        tip_along = min(float(((points[list(FINGERTIPS)] - points[WRIST]) @ axis).min()), 0.0)
        tip = points[WRIST] + tip_along * axis
        metre = breadth / HAND_BREADTH  # [px / m] at the hand
        reach = max(MODEL_HAND_LENGTH * metre, -tip_along + length)  # at least past the wrist
        far = tip + min(reach, float(np.hypot(h, w))) * axis
        width = max(2 * MODEL_HAND_RADIUS * metre, 1.0)
        across = np.array([-axis[1], axis[0]]) * width / 2
        band = np.array([tip - across, tip + across, far + across, far - across])
        cv2.fillPoly(masks[k], [np.round((band - 0.5) * 16).astype(np.int32)], 1, shift=4)
    return masks.astype(bool)
