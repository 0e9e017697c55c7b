"""The pinhole camera of the data contract (``docs/formats.md``): intrinsics, in NumPy.

Image coordinates are continuous, with the centre of pixel (row i, column j) at
(j + 0.5, i + 0.5). The extrinsics (height, elevation) and the projection that the
optimiser differentiates live in :mod:`warpskill.engine.projection`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Intrinsics", "default_intrinsics"]


def default_intrinsics(height: int, width: int) -> np.ndarray:
    """The paper's intrinsics for an image of ``height`` x ``width`` pixels.

    Horizontal field of view 80 deg, vertical 60 deg, principal point at the image centre.

    Returns:
        (3, 3) float64 matrix K.
    """
    fx = width / (2.0 * math.tan(math.radians(40.0)))
    fy = height / (2.0 * math.tan(math.radians(30.0)))
    return np.array([[fx, 0.0, width / 2.0], [0.0, fy, height / 2.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Intrinsics:
    """Fixed intrinsics of an image: ``K`` (3, 3) [px] and ``image_size`` (H, W) [px]."""

    K: np.ndarray
    image_size: tuple[int, int]

    @classmethod
    def default(cls, height: int, width: int) -> "Intrinsics":
        """The paper's default intrinsics for an ``height`` x ``width`` image."""
        return cls(default_intrinsics(height, width), (int(height), int(width)))

    def resized(self, height: int, width: int) -> "Intrinsics":
        """The same camera seen through an image resampled to ``height`` x ``width``.

        Continuous pixel coordinates scale exactly, so masks downsampled by area
        averaging line up with renderings made with these intrinsics.
        """
        sy = height / self.image_size[0]
        sx = width / self.image_size[1]
        K = np.diag([sx, sy, 1.0]) @ self.K
        return Intrinsics(K, (int(height), int(width)))

    def scaled(self, factor: float) -> "Intrinsics":
        """Intrinsics for the image scaled by ``factor`` (rounded to whole pixels)."""
        H, W = self.image_size
        return self.resized(max(1, round(H * factor)), max(1, round(W * factor)))
