"""A phone video outlined on one frame, the hand left out: the hand found, the objects followed.

The user outlines the manipulated object and the static objects on one frame
(:func:`warpskill.data.readers.polygons.read_polygons` without a ``hand`` key).
:func:`footage_masks` then

1. finds every hand in every frame (:func:`.hand_landmarks.find_hands`, MediaPipe's hand
   landmarker with following between detections), and in frames where it sees none, a
   hand it missed by colour and motion (:func:`.hand_regions.hand_regions`);
2. follows the outlined objects through the clip, both ways from the outlined frame, with
   the hands' masks as known occluders (:func:`.following.follow_outlines`);
3. keeps the hand that touches the object where several are seen (:func:`.hands.choose_hand`);
4. reads the contact from the landmarks: a fingertip on or at the object's whole mask (its
   part hidden by the hand included) (:func:`.touch.detections_from_landmarks`), filtered
   as the paper filters a detector's output (:func:`warpskill.data.contact.filter_contact`);
   where only a hand region was found, that region touching the object;
5. follows the object again where that contact says the hand holds it: an object with too
   few corners of its own then moves with the hand, not with the background.

The hand mask given to the optimiser is the model hand drawn along the found hand
(:func:`.model_hand.model_hand_masks`: the hand as a ruler); the found hand's own shape
(:func:`.hands.hand_masks`) is what occludes the objects and what ``bench footage``
compares with people's boxes.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from warpskill.contract.vocabulary import OBJECT
from warpskill.data.contact import UNKNOWN, detections_from_masks, filter_contact
from warpskill.data.footage.following import follow_outlines, visible_masks
from warpskill.data.footage.hand_landmarks import HandTracks, find_hands
from warpskill.data.footage.hand_regions import hand_regions
from warpskill.data.footage.hands import choose_hand, hand_masks
from warpskill.data.footage.model_hand import model_hand_masks
from warpskill.data.footage.touch import detections_from_landmarks


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


def footage_masks(frames: np.ndarray, key_frame: int, key_masks: dict[str, np.ndarray], *,
                  tracks: HandTracks | None = None, regions: np.ndarray | None = None) -> FootageMasks:
    """The hand found and the outlined objects followed through a clip (see the module docstring).

    Args:
        frames: (N, H, W, 3) uint8 RGB frames.
        key_frame: the outlined frame's index.
        key_masks: ``object`` and ``static_k`` -> (H, W) bool masks on the outlined frame.
        tracks, regions: the clip's hands when already found (:func:`find_hands` and
            :func:`hand_regions` of these frames, e.g. by an outline's proposal); None finds them.

    Returns:
        The masks, the chosen hand's landmarks and the contact (all empty / NaN / off where
        no hand is found: the caller decides whether that is an error).

    Raises:
        ImportError: MediaPipe is not installed (the ``video`` extra).
    """
    n, h, w = frames.shape[:3]
    tracks = find_hands(frames) if tracks is None else tracks
    regions = hand_regions(frames, tracks) if regions is None else regions  # where no landmark hand is
    every_hand = regions.copy()
    for landmarks in tracks.all_landmarks():
        every_hand |= hand_masks(landmarks, (h, w), forearm=True)
    whole = follow_outlines(frames, key_frame, key_masks, occluder=every_hand)
    objects = visible_masks(whole, every_hand)
    landmarks = choose_hand(tracks, objects[OBJECT])
    contact = _contact(landmarks, regions, whole[OBJECT], objects[OBJECT])
    if contact.any():  # followed again: where held, the object moves with the hand
        whole = follow_outlines(frames, key_frame, key_masks, occluder=every_hand, carried={OBJECT: contact})
        objects = visible_masks(whole, every_hand)
        contact = _contact(landmarks, regions, whole[OBJECT], objects[OBJECT])
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
