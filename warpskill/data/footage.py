"""A phone video outlined on one frame, the hand left out: the hand found, the objects followed.

The user outlines the manipulated object and the static objects on one frame
(:func:`warpskill.data.read_polygons` without a ``hand`` key). :func:`footage_masks` then

1. finds every hand in every frame (:func:`warpskill.data.hand_landmarks.find_hands`,
   MediaPipe's hand landmarker with following between detections), and in frames where it
   sees none, a hand it missed by colour and motion
   (:func:`warpskill.data.hand_regions.hand_regions`);
2. follows the outlined objects through the clip, both ways from the outlined frame, with
   the hands' masks as known occluders (:func:`warpskill.data.following.follow_objects`);
3. keeps the hand that touches the object where several are seen
   (:func:`warpskill.data.hands.choose_hand`);
4. reads the contact from the landmarks: a fingertip on or at the object's whole mask (its
   part hidden by the hand included)
   (:func:`warpskill.data.contact.detections_from_landmarks`), filtered as the paper filters a
   detector's output (:func:`warpskill.data.contact.filter_contact`); where only a hand
   region was found, that region touching the object;
5. follows the object again where that contact says the hand holds it: an object with too
   few corners of its own then moves with the hand, not with the background.

The hand as a ruler: the optimiser's hand is a cylinder of known width
(:data:`MODEL_HAND_WIDTH`) and reads the scene's scale off the hand mask's apparent width
(``warpskill.optimizer.measurements.hand_depth``). So the hand mask given to it,
:func:`model_hand_masks`, is that cylinder's silhouette drawn along the found hand (from the
fingertips through the wrist and on along the forearm) with the width that the landmarks'
palm breadth measures for an adult hand (:data:`warpskill.nouns.typical.HAND_BREADTH`): the
hand's apparent size in every frame where it is seen becomes the scene's scale. The found
hand's own shape (:func:`warpskill.data.hands.hand_masks`) is what occludes the objects and
what ``bench footage`` compares with people's boxes.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from warpskill.data.contact import (
    UNKNOWN,
    detections_from_landmarks,
    detections_from_masks,
    filter_contact,
)
from warpskill.data.following import follow_outlines, visible_masks
from warpskill.data.hand_landmarks import FINGERTIPS, MIDDLE_KNUCKLE, WRIST, find_hands, hand_size
from warpskill.data.hand_regions import hand_regions
from warpskill.data.hands import choose_hand, hand_masks
from warpskill.nouns.typical import HAND_BREADTH

MODEL_HAND_WIDTH, MODEL_HAND_LENGTH = 0.08, 0.40
"""[m] the optimiser's hand: a cylinder 8 cm across and 40 cm long
(``warpskill.engine.primitives.HAND_RADIUS`` x 2 and ``HAND_LENGTH``; a test holds them
equal, as the data layer does not import the engine)."""


@dataclasses.dataclass(frozen=True)
class FootageMasks:
    """The masks and the contact of a clip whose hand was found.

    Attributes:
        hand: (N, H, W) bool, the optimiser's hand: the model cylinder's silhouette along
            the found hand (:func:`model_hand_masks`), or the hand's region where only that
            was found; empty where no hand is seen.
        found_hand: (N, H, W) bool, the found hand's own shape (no forearm; a region with
            what is in view of the forearm).
        objects: label -> (N, H, W) bool visible masks (``object``, ``static_0``, ...).
        landmarks: (N, 21, 2) the chosen hand's landmarks (x, y) [px]; NaN rows where none
            (also where only a region was found: contact is unknown there).
        contact: (N,) bool, the filtered contact signal.
    """

    hand: np.ndarray
    found_hand: np.ndarray
    objects: dict[str, np.ndarray]
    landmarks: np.ndarray
    contact: np.ndarray


def footage_masks(frames: np.ndarray, key_frame: int, key_masks: dict[str, np.ndarray]) -> FootageMasks:
    """The hand found and the outlined objects followed through a clip (see the module docstring).

    Args:
        frames: (N, H, W, 3) uint8 RGB frames.
        key_frame: the outlined frame's index.
        key_masks: ``object`` and ``static_k`` -> (H, W) bool masks on the outlined frame.

    Returns:
        The masks, the chosen hand's landmarks and the contact (all empty / NaN / off where
        no hand is found: the caller decides whether that is an error).

    Raises:
        ImportError: MediaPipe is not installed (the ``video`` extra).
    """
    n, h, w = frames.shape[:3]
    tracks = find_hands(frames)
    regions = hand_regions(frames, tracks)  # where no landmark hand is
    every_hand = regions.copy()
    for landmarks in tracks.all_landmarks():
        every_hand |= hand_masks(landmarks, (h, w), forearm=True)
    whole = follow_outlines(frames, key_frame, key_masks, occluder=every_hand)
    objects = visible_masks(whole, every_hand)
    landmarks = choose_hand(tracks, objects["object"])
    contact = _contact(landmarks, regions, whole["object"], objects["object"])
    if contact.any():  # followed again: where held, the object moves with the hand
        whole = follow_outlines(frames, key_frame, key_masks, occluder=every_hand, carried={"object": contact})
        objects = visible_masks(whole, every_hand)
        contact = _contact(landmarks, regions, whole["object"], objects["object"])
    return FootageMasks(
        hand=model_hand_masks(landmarks, (h, w)) | regions,
        found_hand=hand_masks(landmarks, (h, w), forearm=False) | regions,
        objects=objects,
        landmarks=landmarks,
        contact=contact,
    )


def _contact(landmarks: np.ndarray, regions: np.ndarray, whole: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """(N,) bool: fingertips on or at the object's whole masks (where only a hand region was
    found, that region touching them), through the paper's filter (which reads the object's
    motion off its visible masks)."""
    detections = detections_from_landmarks(landmarks, whole)
    by_region = (detections == UNKNOWN) & regions.reshape(len(regions), -1).any(axis=1)
    detections[by_region] = detections_from_masks(regions[by_region], whole[by_region])
    return filter_contact(detections, visible)


def model_hand_masks(landmarks: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """The optimiser's hand drawn along found hands: per frame a band as wide as the model
    cylinder (:data:`MODEL_HAND_WIDTH`) at the scale the hand's apparent breadth gives
    (:func:`warpskill.data.hand_landmarks.hand_size`, an adult's
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
        width = max(MODEL_HAND_WIDTH * metre, 1.0)
        across = np.array([-axis[1], axis[0]]) * width / 2
        band = np.array([tip - across, tip + across, far + across, far - across])
        cv2.fillPoly(masks[k], [np.round((band - 0.5) * 16).astype(np.int32)], 1, shift=4)
    return masks.astype(bool)
