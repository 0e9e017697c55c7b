"""NumPy geometry of the contract's primitives: cuboid corners, frames from an axis, motion blends."""

from __future__ import annotations

import numpy as np

__all__ = ["CORNER_SIGNS", "cuboid_corners", "frame_from_axis", "min_jerk"]

# Signs of a unit cube's 8 corners, (8, 3).
#: (8, 3) corner signs of a unit cube, x slowest, z fastest.
CORNER_SIGNS = np.array([(x, y, z) for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def cuboid_corners(pos: np.ndarray, rot: np.ndarray, size: np.ndarray) -> np.ndarray:
    """World corners of cuboids centred at ``pos``, rotated by ``rot``, edge lengths ``size``.

    Args:
        pos: (..., 3) centres [m].
        rot: (..., 3, 3) rotations (local to world).
        size: (..., 3) full edge lengths [m] along the local axes.

    Returns:
        (..., 8, 3) corners [m].
    """
    local = CORNER_SIGNS * (np.asarray(size)[..., None, :] / 2.0)
    return np.asarray(pos)[..., None, :] + local @ np.swapaxes(rot, -1, -2)


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


def min_jerk(s: np.ndarray) -> np.ndarray:
    """The minimum-jerk blend 10 s^3 - 15 s^4 + 6 s^5 of the phase ``s`` clipped to [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5
