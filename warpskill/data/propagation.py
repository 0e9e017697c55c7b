"""Masks for a whole video from polygons drawn on one frame.

The user outlines the hand and the objects on one frame (:func:`read_polygons`); the masks
are carried to the other frames, forward and backward from that frame, one frame at a
time: dense optical flow (OpenCV's Farneback) between consecutive frames, inside the
visible part of each mask and away from its edge, fits a similarity transform (RANSAC)
that moves the mask; a refinement step cleans it (morphological opening and closing,
holes filled, the largest blob kept). Each label keeps its whole shape, so a part hidden
for a while (the object behind the hand) comes back; labels given first are in front
(give the hand first, then the manipulated object, then static objects).

Limits, honestly: errors accumulate frame by frame, so masks drift on long videos; flow
follows texture, so uniform objects, motion blur and large motions (more than about a
tenth of the image per frame) lose parts of the mask; a mask moves as a whole (a
similarity per frame), so deforming shapes (fingers closing) are followed only roughly; an object that leaves the view or is
fully occluded does not come back; a part that is hidden on the annotated frame is never
recovered; thin structures (a fork's prongs) erode away. For real work a learned
propagator (STCN, XMem) is much better: its per-frame label images read with
:func:`warpskill.data.readers.read_label_images`.
"""

from __future__ import annotations

import json
import os

import cv2
import numpy as np

from warpskill.contract.demonstration import DemonstrationError
from warpskill.data.masks import largest_component

EDGE_PX = 3
"""Flow this close to a mask's edge [px] is not used to move it."""

MIN_POINTS = 6
"""Fewest visible mask pixels whose flow moves a mask; a mask seen less vanishes."""

LABELS = ("hand", "object", "static")
"""Polygon labels: ``hand``, ``object`` and ``static`` or ``static_<k>`` for static objects."""


def read_polygons(path: str | os.PathLike, image_size: tuple[int, int]) -> tuple[int, dict[str, np.ndarray]]:
    """Read the polygons drawn on one frame.

    The JSON is ``{"frame": k, "polygons": [{"label": "hand", "points": [[x, y], ...]}, ...]}``
    with k the 0-based frame index and points in pixel coordinates (continuous, (0, 0) the
    top-left corner of the image); several polygons of one label are united.

    Args:
        path: the JSON file.
        image_size: (H, W) of the video frames [px].

    Returns:
        The frame index and label -> (H, W) bool mask.

    Raises:
        DemonstrationError: naming the file and the key, for a malformed file, an unknown
            label, fewer than 3 points, or no ``hand`` or ``object`` polygon.
        FileNotFoundError: ``path`` does not exist.
    """
    with open(path) as handle:
        try:
            data = json.load(handle)
        except json.JSONDecodeError as exc:
            raise DemonstrationError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("frame"), int) or data["frame"] < 0:
        raise DemonstrationError(f"{path}: key 'frame': expected a frame index >= 0")
    if not isinstance(data.get("polygons"), list):
        raise DemonstrationError(f"{path}: key 'polygons': expected a list of {{label, points}}")
    masks: dict[str, np.ndarray] = {}
    for index, polygon in enumerate(data["polygons"]):
        where = f"{path}: polygons[{index}]"
        label = polygon.get("label") if isinstance(polygon, dict) else None
        if not isinstance(label, str) or label.split("_")[0] not in LABELS:
            raise DemonstrationError(f"{where}: label {label!r}: expected hand, object, static or static_<k>")
        try:
            points = np.asarray(polygon["points"], dtype=float)
        except (KeyError, TypeError, ValueError):
            raise DemonstrationError(f"{where}: key 'points': expected [[x, y], ...]") from None
        if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3 or not np.isfinite(points).all():
            raise DemonstrationError(f"{where}: key 'points': expected at least 3 finite [x, y] pairs")
        mask = np.zeros(image_size, dtype=np.uint8)
        cv2.fillPoly(mask, [np.round((points - 0.5) * 16).astype(np.int32)], 1, shift=4)
        masks[label] = masks.get(label, np.zeros(image_size, dtype=bool)) | mask.astype(bool)
    missing = [label for label in ("hand", "object") if label not in masks]
    if missing:
        raise DemonstrationError(f"{path}: no polygon labelled {' or '.join(missing)}")
    return data["frame"], masks


def propagate_masks(
    frames: np.ndarray, key_frame: int, key_masks: dict[str, np.ndarray], *, refine: bool = True
) -> dict[str, np.ndarray]:
    """Carry masks from ``key_frame`` to every frame of the video (see the module docstring).

    Args:
        frames: (N, H, W, 3) uint8 RGB video frames.
        key_frame: index of the annotated frame.
        key_masks: label -> (H, W) bool mask on the annotated frame.
        refine: apply the refinement step after each warp.

    Returns:
        label -> (N, H, W) bool visible masks; each pixel belongs to one label at most,
        the first in ``key_masks``' order that covers it.

    Raises:
        ValueError: frames that are not (N, H, W, 3) uint8, ``key_frame`` out of range, or a
            mask of another size.
    """
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[3] != 3 or frames.dtype != np.uint8:
        raise ValueError(f"frames: expected (N, H, W, 3) uint8, got {frames.dtype} of shape {frames.shape}")
    n, h, w = frames.shape[:3]
    if not 0 <= key_frame < n:
        raise ValueError(f"key_frame: {key_frame} outside 0..{n - 1}")
    labels = list(key_masks)
    for label in labels:
        if np.shape(key_masks[label]) != (h, w):
            raise ValueError(f"key_masks[{label!r}]: expected shape {(h, w)}, got {np.shape(key_masks[label])}")
    gray = [cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY) for frame in frames]
    key = np.stack([np.asarray(key_masks[label], dtype=bool) for label in labels])
    out = np.zeros((len(labels), n, h, w), dtype=bool)
    out[:, key_frame] = key
    for step in (1, -1):
        whole = key  # each label's mask including its parts hidden behind earlier labels
        for k in range(key_frame + step, n if step > 0 else -1, step):
            flow = cv2.calcOpticalFlowFarneback(gray[k - step], gray[k], None, 0.5, 3, 15, 3, 5, 1.2, 0)
            whole = np.stack([_moved(mask, seen, flow) for mask, seen in zip(whole, out[:, k - step])])
            if refine:
                whole = np.stack([_refine(mask) for mask in whole])
            out[:, k] = _in_front(whole)
    return dict(zip(labels, out))


def _in_front(whole: np.ndarray) -> np.ndarray:
    """(L, H, W) whole masks -> visible masks: each pixel to the first label covering it."""
    covered = np.cumsum(whole, axis=0) > 0
    visible = whole.copy()
    visible[1:] &= ~covered[:-1]
    return visible


def _moved(whole: np.ndarray, visible: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """A (H, W) mask moved to the next frame by the similarity transform (rotation, scale,
    shift) fitted with RANSAC to the forward ``flow`` inside its visible part, away from the
    edge (flow there mixes the object with what surrounds it)."""
    h, w = whole.shape
    image = visible.astype(np.uint8)
    interior = cv2.erode(image, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (EDGE_PX * 2 + 1,) * 2))
    ys, xs = np.nonzero(interior if interior.sum() >= MIN_POINTS else image)
    if len(xs) < MIN_POINTS:
        return np.zeros((h, w), dtype=bool)
    source = np.stack([xs, ys], axis=1).astype(np.float32)
    target = source + flow[ys, xs]
    transform, _ = cv2.estimateAffinePartial2D(source, target, method=cv2.RANSAC, ransacReprojThreshold=1.0)
    if transform is None:
        transform = np.hstack([np.eye(2), np.median(target - source, axis=0)[:, None]]).astype(np.float32)
    return cv2.warpAffine(whole.astype(np.float32), transform, (w, h), flags=cv2.INTER_LINEAR) >= 0.5


def _refine(mask: np.ndarray) -> np.ndarray:
    """Opening and closing (3 x 3), holes filled, the largest blob kept."""
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    image = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, kernel)
    image = cv2.morphologyEx(image, cv2.MORPH_CLOSE, kernel)
    contours, _ = cv2.findContours(image, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    filled = np.zeros_like(image)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    return largest_component(filled.astype(bool)[None])[0]
