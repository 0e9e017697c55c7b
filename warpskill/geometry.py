"""NumPy geometry the layers share: rotations about z and from an axis, quaternions, cuboid
corners and extents, the minimum-jerk blend, and the frames a grasp signal holds the object in.

A leaf below the contract, the robot, the exports and the pictures: imports NumPy only.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["CORNER_SIGNS", "HELD", "NEVER_HELD", "cuboid_corners", "frame_from_axis", "heading", "held_span",
           "is_held", "min_jerk", "quat_multiply", "quaternions", "release_frame", "rot_z", "support_extent"]

HELD = 0.5
"""``grasped`` above this: the hand holds (or touches) the object."""

NEVER_HELD = f"the hand never holds or touches the object (grasped <= {HELD} in every frame)"
"""Why a grasp signal that holds in no frame has no held span."""

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


def support_extent(rot: np.ndarray, size: np.ndarray, direction: np.ndarray) -> float:
    """Half the extent [m] of a cuboid (rotation ``rot`` (3, 3), edge lengths ``size`` (3,)) along
    ``direction`` (3,), a unit vector."""
    return 0.5 * float(np.abs(rot.T @ direction) @ size)


def rot_z(angle: float) -> np.ndarray:
    """(3, 3) the rotation by ``angle`` [rad] about the world z axis."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def heading(rot: np.ndarray) -> float:
    """Yaw [rad] of a cuboid of rotation ``rot`` (3, 3): the heading of its local x about z.

    Where local x is near vertical (the cuboid on its side), local y's heading less pi/2.
    """
    if math.hypot(rot[0, 0], rot[1, 0]) >= 0.5:
        return math.atan2(rot[1, 0], rot[0, 0])
    return math.atan2(rot[1, 1], rot[0, 1]) - math.pi / 2


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


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(4,) the Hamilton product ``a b`` of quaternions (w, x, y, z): ``b``'s rotation, then ``a``'s."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw])


def quaternions(R: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) of rotation matrices (..., 3, 3) (Shepperd's method)."""
    R = np.asarray(R, float)
    m = {(i, j): R[..., i, j] for i in range(3) for j in range(3)}
    candidates = np.stack(
        [
            np.stack([1 + m[0, 0] + m[1, 1] + m[2, 2], m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]], -1),
            np.stack([m[2, 1] - m[1, 2], 1 + m[0, 0] - m[1, 1] - m[2, 2], m[0, 1] + m[1, 0], m[0, 2] + m[2, 0]], -1),
            np.stack([m[0, 2] - m[2, 0], m[0, 1] + m[1, 0], 1 - m[0, 0] + m[1, 1] - m[2, 2], m[1, 2] + m[2, 1]], -1),
            np.stack([m[1, 0] - m[0, 1], m[0, 2] + m[2, 0], m[1, 2] + m[2, 1], 1 - m[0, 0] - m[1, 1] + m[2, 2]], -1),
        ],
        axis=-2,
    )  # (..., 4 candidates, (w, x, y, z)), candidate i is 4 q_i q
    diagonal = np.stack([candidates[..., i, i] for i in range(4)], axis=-1)
    best = np.take_along_axis(candidates, diagonal.argmax(axis=-1)[..., None, None], axis=-2)[..., 0, :]
    return best / np.linalg.norm(best, axis=-1, keepdims=True)


def min_jerk(s: np.ndarray) -> np.ndarray:
    """The minimum-jerk blend 10 s^3 - 15 s^4 + 6 s^5 of the phase ``s`` clipped to [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def is_held(grasped: np.ndarray) -> np.ndarray:
    """Where the grasp switch ``grasped`` (any shape, 0 .. 1) holds the object (above :data:`HELD`)."""
    return np.asarray(grasped) > HELD


def held_span(grasped: np.ndarray) -> tuple[int, int | None] | None:
    """The first held frame and the frame after the last held one (None: held to the end) of
    ``grasped`` (F,); None where no frame is held (:data:`NEVER_HELD`)."""
    held = np.flatnonzero(is_held(grasped))
    if len(held) == 0:
        return None
    k_off = int(held[-1]) + 1
    return int(held[0]), k_off if k_off < len(grasped) else None


def release_frame(grasped: np.ndarray) -> int:
    """The frame after the last held one of ``grasped`` (F,), the last frame where the video ends
    held (or nothing is held)."""
    span = held_span(grasped)
    return len(grasped) - 1 if span is None or span[1] is None else span[1]
