"""What one view's masks measure of the scene before any optimisation.

Per-frame statistics of a mask stack (visibility, centroid, box, pixels) and the two
readings of the hand mask that fix the scene's scale and the hand's pose: its width at
the tip, which gives the tip's camera depth (the hand is a cylinder of known radius
:data:`~warpskill.engine.primitives.HAND_RADIUS`), and its foreshortening, which gives its
lean towards the camera. :mod:`warpskill.optimizer.guess` builds stage (a)'s first scene
from them.

Image coordinates: pixel centres (u, v) = (column + 0.5, row + 0.5) [px]; "normalised"
coordinates are pixels over the focal lengths (pixels need not be square).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from warpskill.engine.primitives import HAND_LENGTH, HAND_RADIUS

TYPICAL_HAND_TILT = 1.0 / math.sqrt(5.0)
"""A forearm's lean towards the camera: the sine of its angle out of the image plane (27 deg)."""
MAX_HAND_TILT = 0.9
"""The largest lean read off a hand mask: a hand cut by the image border looks shorter than it is."""
MIN_BAND_PIXELS = 6
"""Fewest pixels of a hand mask (or of a slab of it) whose width is read: fewer give no spread."""


class MaskGeometry:
    """Per-frame 2D statistics of masks (N, h, w) in [0, 1], thresholded at 0.5.

    Attributes:
        visible: (N,) bool, the frame's mask is not empty.
        centroid: (N, 2) mean pixel centre (u, v) [px]; NaN where empty.
        box: (N, 4) pixel-edge bounds (u0, v0, u1, v1) [px]; NaN where empty.
    """

    def __init__(self, masks: np.ndarray):
        hard = masks > 0.5
        self.visible = hard.reshape(len(masks), -1).any(1)
        self.centroid = np.full((len(masks), 2), np.nan)
        self.box = np.full((len(masks), 4), np.nan)
        for k in np.flatnonzero(self.visible):
            rows, cols = np.nonzero(hard[k])
            self.centroid[k] = cols.mean() + 0.5, rows.mean() + 0.5
            self.box[k] = cols.min(), rows.min(), cols.max() + 1.0, rows.max() + 1.0
        self._hard = hard

    def pixels(self, k: int) -> np.ndarray:
        """(M, 2) pixel centres (u, v) [px] of frame k's mask."""
        rows, cols = np.nonzero(self._hard[k])
        return np.stack([cols + 0.5, rows + 0.5], -1)


def fill_missing(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``values`` (N, ...) with each invalid frame's value copied from the nearest valid frame
    (``valid``: (N,) bool); the earlier one on a tie.

    Raises:
        ValueError: no frame is valid.
    """
    idx = np.flatnonzero(valid)
    if len(idx) == 0:
        raise ValueError("no valid frame to initialise from")
    nearest = idx[np.abs(np.arange(len(values))[:, None] - idx[None]).argmin(1)]
    return values[nearest]


def band_width(points: np.ndarray, axis: np.ndarray) -> float:
    """Width of a band of points (M, 2) along the unit ``axis`` (2,): sqrt(12) x their standard
    deviation, a uniform band's width, in the points' units."""
    return float(np.sqrt(12.0 * np.var(points @ axis)))


@dataclass
class HandBand:
    """One frame's hand mask as a band in normalised image coordinates.

    Attributes:
        frame: the frame's index.
        pixels: (M, 2) its pixel centres [px].
        points: (M, 2) the same over the focal lengths.
        width: its width across its main axis (:func:`band_width`).
        across, main: (2,) unit axes across and along the band.
        thinnest: one pixel's width in these coordinates, the least width to read.
    """

    frame: int
    pixels: np.ndarray
    points: np.ndarray
    width: float
    across: np.ndarray
    main: np.ndarray
    thinnest: float


def hand_bands(geom: MaskGeometry, K: np.ndarray) -> Iterator[HandBand]:
    """The :class:`HandBand` of each frame whose hand mask holds at least
    :data:`MIN_BAND_PIXELS` pixels (``geom``: the hand's masks; ``K``: (3, 3) intrinsics)."""
    focal = np.array([K[0, 0], K[1, 1]])
    for k in np.flatnonzero(geom.visible):
        pixels = geom.pixels(k)
        if len(pixels) >= MIN_BAND_PIXELS:
            points = pixels / focal
            variances, axes = np.linalg.eigh(np.cov(points.T))
            across, main = axes.T
            yield HandBand(k, pixels, points, float(np.sqrt(12.0 * variances[0])), across, main, 1.0 / focal.max())


def hand_depth(geom: MaskGeometry, targets_of: np.ndarray, K: np.ndarray) -> float | None:
    """Median camera depth [m] of the hand tip over frames, from the mask's width at the tip.

    The hand is a cylinder of known radius R, so a stretch of mask w wide (normalised
    coordinates) lies at depth 2 R / w. The width is measured across the mask's main axis,
    in the slab half a width long that starts at the tip (the hand pixel nearest
    ``targets_of`` (N, 2) [px], the object's centroid): farther up, a hand reaching forwards
    or down comes closer to the camera and widens. None when no frame has a readable slab.

    Args:
        geom: the hand's masks.
        targets_of: (N, 2) the pixel [px] per frame that the hand reaches for.
        K: (3, 3) intrinsics at the masks' resolution.
    """
    depths = []
    for band in hand_bands(geom, K):
        tip = band.points[np.argmin(((band.pixels - targets_of[band.frame]) ** 2).sum(1))]
        along = (band.points - tip) @ band.main
        along = along if np.median(along) >= 0 else -along  # from the tip up the hand
        slab = band.points[(along >= 0) & (along <= 0.5 * band.width)]
        if len(slab) >= MIN_BAND_PIXELS:
            depths.append(2.0 * HAND_RADIUS / max(band_width(slab, band.across), band.thinnest))
    return float(np.median(depths)) if depths else None


def hand_tilt(geom: MaskGeometry, K: np.ndarray) -> float | None:
    """The hand's lean towards the camera: its axis's component along the view, the sine of
    its angle out of the image plane, from its foreshortening.

    The median over frames of sqrt(1 - (L / (5 w))^2), with L and w the mask's length and
    width (:func:`band_width` along and across its main axis) and 5 the cylinder's length
    over its diameter, clipped to [:data:`TYPICAL_HAND_TILT`, :data:`MAX_HAND_TILT`].
    Perspective lengthens the part nearer the camera, so the lean comes out low: only a
    clearly short hand moves the guess off the typical lean. None when no frame has a
    readable band.

    Args:
        geom: the hand's masks.
        K: (3, 3) intrinsics at the masks' resolution.
    """
    leans = []
    for band in hand_bands(geom, K):
        width = max(band_width(band.points, band.across), band.thinnest)
        ratio = band_width(band.points, band.main) / (width * HAND_LENGTH / (2.0 * HAND_RADIUS))
        leans.append(np.sqrt(1.0 - min(ratio, 1.0) ** 2))
    return float(np.clip(np.median(leans), TYPICAL_HAND_TILT, MAX_HAND_TILT)) if leans else None
