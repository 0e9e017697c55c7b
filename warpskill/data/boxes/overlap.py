"""How well masks sit on people's boxes: a mask's bounding box and its IoU with a box."""

from __future__ import annotations

import numpy as np


def mask_box(mask: np.ndarray) -> np.ndarray:
    """The (x0, y0, x1, y1) bounding box [px] of an (H, W) mask; NaN when empty."""
    ys, xs = np.nonzero(mask)
    if not len(xs):
        return np.full(4, np.nan)
    return np.array([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1], dtype=float)


def box_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two (x0, y0, x1, y1) boxes; 0 when either is NaN (empty)."""
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        return 0.0
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    inter = max(w, 0.0) * max(h, 0.0)
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return float(inter / union) if union > 0 else 0.0


def box_ious(masks: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(N,) IoU of each frame's mask's bounding box with the annotated box; NaN in frames
    without a box. ``masks`` (N, H, W) bool, ``boxes`` (N, 4) with NaN rows."""
    out = np.full(len(boxes), np.nan)
    for k in np.flatnonzero(np.isfinite(boxes[:, 0])):
        out[k] = box_iou(mask_box(masks[k]), boxes[k])
    return out
