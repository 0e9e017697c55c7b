"""The robot's own objects: the reconstructed scene with the cuboid sizes the robot handles.

:func:`fit_sizes` gives the manipulated cuboid and the static cuboids new sizes (the user's,
or a substitute for an object the gripper cannot hold) and keeps the demonstration: the
object-centre path in the horizontal plane and every static box's footprint centre stay;
heights follow the sizes, so that each static box keeps its bottom where it was and the
object keeps its gap to its support (the table or a static top; while held, the support's
change is blended linearly from the grasp to the release). Until the contact onset the
object is made to rest on a face (:func:`upright`: a reconstruction's clear tilt would
topple it in the replay before the robot reaches it).

A grasp action (pick up, put ...) on an object wider than the gripper's usable opening on
every face (both horizontal extents at the grasp onset) gets a substitute that fits: its
horizontal extents capped at :data:`SUBSTITUTE_WIDTH`, its height kept. Pushes and pulls
keep any size: they press with closed fingers or hook the far face.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.robot.grasps import FIT_MARGIN
from warpskill.robot.model import MAX_OPENING

__all__ = ["SUBSTITUTE_WIDTH", "USABLE_OPENING", "fit_sizes", "needs_substitute", "upright"]

USABLE_OPENING = MAX_OPENING - FIT_MARGIN
"""[m] widest object edge the gripper closes on."""

UPRIGHT_TILT = 10.0
"""[deg] a cuboid tilted further than this from resting on a face is set upright."""

SUBSTITUTE_WIDTH = USABLE_OPENING - 0.01
"""[m] horizontal extents of a substitute object (the usable opening less a margin)."""


def _sizes(value, shape, what: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != shape or not np.all(np.isfinite(array)) or np.any(array <= 0):
        raise ValueError(f"{what} must be {' x '.join(map(str, shape))} positive sizes [m], got {value!r}")
    return array


def _support(xy: np.ndarray, radius: float, static_pos, static_rot, static_size) -> np.ndarray:
    """(F,) height of the table or the highest static top under each centre ``xy`` (F, 2)."""
    floor = np.zeros(len(xy))
    for k in range(len(static_pos)):
        local = (np.c_[xy, np.zeros(len(xy))] - static_pos[k]) @ static_rot[k]
        inside = np.all(np.abs(local[:, :2]) < static_size[k, :2] / 2 + radius, axis=1)
        top = static_pos[k, 2] + 0.5 * float(np.abs(static_rot[k][2]) @ static_size[k])
        floor = np.where(inside, np.maximum(floor, top), floor)
    return floor


def upright(rot: np.ndarray) -> np.ndarray:
    """(F, 3, 3) the rotations ``rot`` turned so that the cuboid rests on a face, heading kept.

    Where the cuboid axis nearest the world's vertical is tilted by more than
    :data:`UPRIGHT_TILT`, it becomes vertical and the next axis keeps its horizontal
    direction. A cuboid can only rest on a face: a clearly tilted reconstruction would
    topple in the replay before the robot reaches it (a slight tilt just settles).
    """
    out = np.array(rot, dtype=float, copy=True)
    for f, R in enumerate(rot):
        i = int(np.argmax(np.abs(R[2])))
        if abs(R[2, i]) >= math.cos(math.radians(UPRIGHT_TILT)):
            continue  # settles onto its face in the replay
        j, k = (i + 1) % 3, (i + 2) % 3
        col_i = np.array([0.0, 0.0, math.copysign(1.0, R[2, i])])
        col_j = R[:, j] - (R[:, j] @ col_i) * col_i
        if np.linalg.norm(col_j) < 1e-9:  # pragma: no cover - R[:, j] cannot be vertical when R[:, i] is nearest it
            col_j = R[:, k] - (R[:, k] @ col_i) * col_i
            col_j = np.cross(col_j, col_i)
        col_j /= np.linalg.norm(col_j)
        out[f][:, i], out[f][:, j], out[f][:, k] = col_i, col_j, np.cross(col_i, col_j)
    return out


def _onset(recon: Reconstruction) -> int:
    held = np.flatnonzero(recon.grasped > 0.5)
    return int(held[0]) if len(held) else 0


def needs_substitute(recon: Reconstruction, size: np.ndarray) -> bool:
    """Whether a grasp action's cuboid of ``size`` is wider than the usable opening on every face."""
    if str(recon.action).startswith(("push_", "pull_")):
        return False
    R = recon.object_rot[_onset(recon)]
    up = int(np.argmax(np.abs(R[2])))  # the cuboid axis closest to the world's vertical
    return bool(all(size[i] > USABLE_OPENING for i in range(3) if i != up))


def fit_sizes(recon: Reconstruction, *, object_size=None, static_sizes=None,
              keep_size: bool = False) -> tuple[Reconstruction, str]:
    """The reconstruction with the robot's object sizes, and a one-line note ('' when unchanged).

    Args:
        recon: the reconstruction.
        object_size: (3,) [m] the manipulated cuboid's edge lengths (default: reconstructed).
        static_sizes: (K, 3) [m] the static cuboids' edge lengths, one per static object.
        keep_size: never substitute a cuboid the gripper cannot hold (the plan then fails).

    Raises:
        ValueError: sizes of the wrong shape, or a static count other than the reconstruction's.
    """
    size = recon.object_size.copy() if object_size is None else _sizes(object_size, (3,), "the object size")
    statics = recon.static_size.copy()
    if static_sizes is not None and len(static_sizes):
        if len(static_sizes) != recon.num_static:
            raise ValueError(f"{len(static_sizes)} static size(s) given, but the reconstruction has "
                             f"{recon.num_static} static object(s)")
        statics = _sizes(static_sizes, (recon.num_static, 3), "the static sizes")
    notes = []
    if not keep_size and needs_substitute(recon, size):
        R = recon.object_rot[_onset(recon)]
        up = int(np.argmax(np.abs(R[2])))
        old = size.copy()
        size = np.array([s if i == up else min(s, SUBSTITUTE_WIDTH) for i, s in enumerate(size)])
        notes.append(f"object: the {' x '.join(f'{s:.3f}' for s in old)} m cuboid is wider than the gripper's "
                     f"{USABLE_OPENING:.3f} m usable opening on every face: the robot handles a "
                     f"{' x '.join(f'{s:.3f}' for s in size)} m one (height kept; --keep-size refuses instead)")
    rot = recon.object_rot.copy()  # resting until the contact: it must rest on a face (later tilts are noise)
    rot[: _onset(recon) + 1] = upright(recon.object_rot[: _onset(recon) + 1])
    if np.allclose(size, recon.object_size) and np.allclose(statics, recon.static_size) and \
            np.allclose(rot, recon.object_rot, atol=1e-9):
        return recon, "; ".join(notes)
    # Static boxes keep their bottoms.
    static_pos = recon.static_pos.copy()
    for k in range(recon.num_static):
        R = recon.static_rot[k]
        static_pos[k, 2] += 0.5 * float(np.abs(R[2]) @ (statics[k] - recon.static_size[k]))
    # The object keeps its gap to its support, frame by frame (blended while held).
    xy = recon.object_pos[:, :2]
    half_old = 0.5 * np.abs(recon.object_rot[:, 2, :]) @ recon.object_size
    half_new = 0.5 * np.abs(rot[:, 2, :]) @ size
    s_old = _support(xy, 0.5 * min(recon.object_size[:2]), recon.static_pos, recon.static_rot, recon.static_size)
    s_new = _support(xy, 0.5 * min(size[:2]), static_pos, recon.static_rot, statics)
    ds = s_new - s_old
    held = np.flatnonzero(recon.grasped > 0.5)
    if len(held):
        a, b = int(held[0]), min(int(held[-1]) + 1, recon.num_frames - 1)
        if b > a:
            ds[a:b + 1] = np.interp(np.arange(a, b + 1), [a, b], [ds[a], ds[b]])
    object_pos = recon.object_pos.copy()
    object_pos[:, 2] += half_new - half_old + ds
    fitted = dataclasses.replace(recon, object_size=size, object_pos=object_pos, object_rot=rot,
                                 static_pos=static_pos, static_size=statics)
    return fitted, "; ".join(notes)
