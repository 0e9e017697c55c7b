"""Masks for a whole video from polygons drawn on one frame.

The user outlines the hand and the objects on one frame
(:func:`warpskill.data.readers.polygons.read_polygons`: the polygon file of
``docs/formats.md`` or a LabelMe file); the masks
are carried to the other frames, forward and backward from that frame, one frame at a
time: dense optical flow (OpenCV's Farneback) between consecutive frames, inside the
visible part of each mask and away from its edge, fits a similarity transform (RANSAC)
that moves the mask (on small videos the flow is computed on frames enlarged to
:data:`FLOW_MIN_SIDE` px, so that its window does not blur a small object with its
surroundings; on larger ones, a phone's 640 x 480 say, on frames reduced to that size: the
flow's window then spans as much of the scene, at a quarter of the cost); a refinement
step cleans it (in the mask's box alone) (morphological opening and closing,
holes filled, the largest blob kept). Each label keeps its whole shape, so a part hidden
for a while (the object behind the hand) comes back; labels given first are in front
(give the hand first, then the manipulated object, then static objects). Masks live on a
canvas larger than the image, so parts that leave the view come back; the hand's mask,
where it touches the image border on the annotated frame, is extended beyond it (the arm
goes on out of view), so the arm follows the hand into the image.

Limits, honestly: errors accumulate frame by frame, so masks drift on long videos; flow
follows texture, so uniform objects, motion blur and large motions (more than about a
tenth of the image per frame) lose parts of the mask; a mask moves as a whole (a
similarity per frame), so deforming shapes (fingers closing) are followed only roughly; an
object that is fully occluded stops (no flow to follow) and one mostly hidden lags; a part
that is hidden on the annotated frame is never recovered; thin structures (a fork's prongs) erode away. For real work a learned
propagator (STCN, XMem) is much better: its per-frame label images read with
:func:`warpskill.data.readers.mask_files.read_label_images`.
"""

from __future__ import annotations

import cv2
import numpy as np

from warpskill.contract.vocabulary import HAND
from warpskill.data.footage.tracking import FLOW_RANSAC_PX
from warpskill.data.masks import largest_component

EDGE_PX = 3
"""Flow this close to a mask's edge [px] is not used to move it."""

MIN_POINTS = 6
"""Fewest visible mask pixels whose flow moves a mask; a mask seen less vanishes."""

FLOW_MIN_SIDE = 240
"""Optical flow runs on frames scaled until their shorter side has this many px: a smaller
video's enlarged (bicubic), a larger one's reduced (by area)."""

REFINE_MARGIN_PX = 4
"""Zero px kept around a mask's box when refining it: more than the 3 x 3 opening and closing reach."""

EXTENDED_LABELS = (HAND,)
"""Labels whose mask is extended beyond the image border it touches on the annotated frame."""


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
    key = np.stack([np.asarray(key_masks[label], dtype=bool) for label in labels])
    scale = FLOW_MIN_SIDE / min(h, w)
    gray = [cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY) for frame in frames]
    if scale != 1:
        sampling = cv2.INTER_CUBIC if scale > 1 else cv2.INTER_AREA
        gray = [cv2.resize(image, None, fx=scale, fy=scale, interpolation=sampling) for image in gray]
    pad = max(h, w) // 2  # the canvas around the image on which whole masks live
    canvas = np.stack([
        cv2.copyMakeBorder(mask.astype(np.uint8), pad, pad, pad, pad,
                           cv2.BORDER_REPLICATE if label in EXTENDED_LABELS else cv2.BORDER_CONSTANT, value=0)
        for label, mask in zip(labels, key)
    ]).astype(bool)
    out = np.zeros((len(labels), n, h, w), dtype=bool)
    out[:, key_frame] = key
    for step in (1, -1):
        whole = canvas  # each label's mask including its parts hidden behind earlier labels or out of view
        for k in range(key_frame + step, n if step > 0 else -1, step):
            flow = cv2.calcOpticalFlowFarneback(gray[k - step], gray[k], None, 0.5, 3, 15, 3, 5, 1.2, 0)
            whole = np.stack([_moved(mask, seen, flow, scale, pad) for mask, seen in zip(whole, out[:, k - step])])
            if refine:
                whole = np.stack([_refine(mask) for mask in whole])
            out[:, k] = _in_front(whole[:, pad : pad + h, pad : pad + w])
    return dict(zip(labels, out))


def _in_front(whole: np.ndarray) -> np.ndarray:
    """(L, H, W) whole masks -> visible masks: each pixel to the first label covering it."""
    visible = whole.copy()
    covered = whole[0].copy()
    for mask, seen in zip(whole[1:], visible[1:]):
        seen &= ~covered
        covered |= mask
    return visible


def _moved(whole: np.ndarray, visible: np.ndarray, flow: np.ndarray, scale: float, pad: int) -> np.ndarray:
    """A whole mask on the canvas (the image with ``pad`` px all round) moved to the next
    frame by the similarity transform (rotation, scale, shift) fitted with RANSAC to the
    forward ``flow`` (computed on frames enlarged by ``scale``) inside its (H, W) visible
    part, away from the edge (flow there mixes the object with what surrounds it)."""
    image = visible.astype(np.uint8)
    interior = cv2.erode(image, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (EDGE_PX * 2 + 1,) * 2))
    ys, xs = np.nonzero(interior if interior.sum() >= MIN_POINTS else image)
    if len(xs) < MIN_POINTS:
        return np.zeros(whole.shape, dtype=bool)
    source = np.stack([xs, ys], axis=1).astype(np.float32)
    fy = np.clip(np.round((ys + 0.5) * scale - 0.5), 0, flow.shape[0] - 1).astype(int)
    fx = np.clip(np.round((xs + 0.5) * scale - 0.5), 0, flow.shape[1] - 1).astype(int)
    target = source + flow[fy, fx] / scale
    transform, _ = cv2.estimateAffinePartial2D(source, target, method=cv2.RANSAC, ransacReprojThreshold=FLOW_RANSAC_PX)
    if transform is None:
        transform = np.hstack([np.eye(2), np.median(target - source, axis=0)[:, None]]).astype(np.float32)
    linear = transform[:, :2]
    on_canvas = np.hstack([linear, (transform[:, 2] + pad - linear @ np.array([pad, pad]))[:, None]])
    height, width = whole.shape
    moved = cv2.warpAffine(whole.astype(np.float32), on_canvas.astype(np.float32), (width, height), flags=cv2.INTER_LINEAR)
    return moved >= 0.5


def _refine(mask: np.ndarray) -> np.ndarray:
    """Opening and closing (3 x 3), holes filled, the largest blob kept; worked in the mask's box
    with a margin of :data:`REFINE_MARGIN_PX` (the same as on the whole canvas, at a fraction of the cost)."""
    refined = np.zeros_like(mask)
    ys, xs = np.nonzero(mask.any(axis=1))[0], np.nonzero(mask.any(axis=0))[0]
    if not len(ys):
        return refined
    y0, x0 = max(ys[0] - REFINE_MARGIN_PX, 0), max(xs[0] - REFINE_MARGIN_PX, 0)
    box = (slice(y0, ys[-1] + 1 + REFINE_MARGIN_PX), slice(x0, xs[-1] + 1 + REFINE_MARGIN_PX))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    image = cv2.morphologyEx(mask[box].astype(np.uint8), cv2.MORPH_OPEN, kernel)
    image = cv2.morphologyEx(image, cv2.MORPH_CLOSE, kernel)
    contours, _ = cv2.findContours(image, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    filled = np.zeros_like(image)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    refined[box] = largest_component(filled.astype(bool)[None])[0]
    return refined
