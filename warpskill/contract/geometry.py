"""Frames from an axis (the shared NumPy geometry is :mod:`warpskill.geometry`)."""

from __future__ import annotations

import numpy as np

__all__ = ["frame_from_axis"]


def frame_from_axis(axis: np.ndarray) -> np.ndarray:
    """Rotations whose local z is ``axis`` (normalised), x horizontal where the axis is not near-vertical.

    Args:
        axis: (..., 3) direction(s), any non-zero length.

    Returns:
        (..., 3, 3) rotations (local to world), columns x, y, z.
    """
    z = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    helper = np.where(np.abs(z[..., 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], -1)

