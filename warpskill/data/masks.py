"""Mask clean-up, as the paper post-processes its segmentations: keep the largest blob per
object and frame, optionally drop specks, and optionally subsample in space and time.

All functions are pure: they take (N, H, W) bool arrays (one object over N frames) and
return new arrays.
"""

from __future__ import annotations

import cv2
import numpy as np

SPECK_AREA_FRACTION = 0.1
"""A frame whose mask covers less than this fraction of the object's median visible area is a
speck, when specks are dropped (:func:`drop_specks`)."""

DEFAULT_MIN_AREA_FRACTION = 0.0
"""The readers' speck threshold (:func:`clean_masks`): 0 keeps every frame. An object going
behind another shows as a sliver a tenth of its usual area, which an area rule cannot tell
from a speck; the largest blob alone placed the synthetic masks sets' objects and hands
closer to the truth (docs/results-history.md)."""


def largest_component(masks: np.ndarray) -> np.ndarray:
    """Keep only the largest 8-connected component of each frame.

    Args:
        masks: (N, H, W) bool, one object over N frames.

    Returns:
        (N, H, W) bool; empty frames stay empty.
    """
    masks = _check_masks(masks)
    out = np.zeros_like(masks)
    for k, frame in enumerate(masks):
        if not frame.any():
            continue
        count, labels, stats, _ = cv2.connectedComponentsWithStats(frame.astype(np.uint8), connectivity=8)
        largest = 1 + int(np.argmax(stats[1:count, cv2.CC_STAT_AREA]))
        out[k] = labels == largest
    return out


def drop_specks(masks: np.ndarray, min_fraction: float = SPECK_AREA_FRACTION) -> np.ndarray:
    """Empty the frames whose mask is a speck: smaller than ``min_fraction`` of the median
    area over the frames where the object is visible.

    Args:
        masks: (N, H, W) bool.
        min_fraction: in [0, 1); 0 keeps every frame.

    Returns:
        (N, H, W) bool.

    Raises:
        ValueError: ``min_fraction`` outside [0, 1).
    """
    masks = _check_masks(masks)
    if not 0.0 <= min_fraction < 1.0:
        raise ValueError(f"min_fraction: expected a value in [0, 1), got {min_fraction}")
    areas = masks.reshape(len(masks), -1).sum(axis=1)
    visible = areas > 0
    if not visible.any():
        return masks.copy()
    speck = visible & (areas < min_fraction * np.median(areas[visible]))
    out = masks.copy()
    out[speck] = False
    return out


def clean_masks(masks: np.ndarray, min_fraction: float = DEFAULT_MIN_AREA_FRACTION) -> np.ndarray:
    """The paper's post-processing: :func:`largest_component`, then :func:`drop_specks`
    (which keeps every frame at the default ``min_fraction`` of 0).

    Args:
        masks: (N, H, W) bool.
        min_fraction: see :func:`drop_specks`.

    Returns:
        (N, H, W) bool.
    """
    return drop_specks(largest_component(masks), min_fraction)


def subsample(masks: np.ndarray, *, spatial: int = 1, temporal: int = 1) -> np.ndarray:
    """Keep every ``temporal``-th frame and shrink each by ``spatial`` (area average, a
    pixel stays set when at least half covered).

    Args:
        masks: (N, H, W) bool.
        spatial: integer shrink factor >= 1 (H and W are rounded down to multiples of it).
        temporal: integer frame step >= 1 (the frame rate divides by it).

    Returns:
        (ceil(N / temporal), H // spatial, W // spatial) bool.

    Raises:
        ValueError: a factor that is not an integer >= 1, or larger than the image.
    """
    masks = _check_masks(masks)
    for name, factor in (("spatial", spatial), ("temporal", temporal)):
        if not isinstance(factor, (int, np.integer)) or factor < 1:
            raise ValueError(f"{name}: expected an integer >= 1, got {factor!r}")
    masks = masks[::temporal]
    if spatial == 1:
        return masks.copy()
    n, h, w = masks.shape
    if h < spatial or w < spatial:
        raise ValueError(f"spatial: factor {spatial} is larger than the {h} x {w} image")
    h, w = h // spatial, w // spatial
    blocks = masks[:, : h * spatial, : w * spatial].reshape(n, h, spatial, w, spatial)
    return blocks.mean(axis=(2, 4)) >= 0.5


def _check_masks(masks: np.ndarray) -> np.ndarray:
    """``masks`` as a (N, H, W) bool array; raises ValueError otherwise."""
    masks = np.asarray(masks)
    if masks.ndim != 3:
        raise ValueError(f"masks: expected shape (N, H, W), got {masks.shape}")
    if masks.dtype != bool:
        raise ValueError(f"masks: expected bool, got dtype {masks.dtype}")
    return masks
