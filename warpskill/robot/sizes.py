"""The robot's own objects: the reconstructed scene with the cuboid sizes the robot handles.

:func:`fit_sizes` gives the manipulated cuboid and the static cuboids new sizes (the user's,
or a substitute for an object the gripper cannot hold) and keeps the demonstration: the
object-centre path in the horizontal plane and every static box's footprint centre stay;
heights follow the sizes, so that each static box keeps its bottom where it was and the
object keeps its gap to its support (the table or a static top; while held, the support's
change is blended linearly from the grasp to the release). Until the contact onset the
object rests where the hand first touches it (nothing moves it before), on a face
(:func:`upright`: a reconstruction's tilt would stand it on an edge, and a tall one would
fall in the replay before the robot reaches it).

An object already held in the first frame was carried into view (or moved before it) and
never seen resting: :func:`rest_until` makes the robot's version of such a demonstration,
in which the object rests below the frame the robot takes it over at
(:func:`~warpskill.robot.retargeting.robot_reconstruction` chooses that frame), and
:func:`clear_path` makes every held path one the arm can track (never inside its support,
no steps down).

A grasp action (pick up, put ...) on an object wider than the gripper's usable opening on
every face (both horizontal extents at the grasp onset) keeps its size where it is an open
vessel whose rim the gripper holds (its noun :func:`~warpskill.nouns.typical.is_open_topped`,
its wall tall enough: :func:`~warpskill.robot.grasps.rim_fits`), and otherwise gets a
substitute that fits: its horizontal extents capped at :data:`SUBSTITUTE_WIDTH`, its height
kept. The note says which, and why. Pushes and pulls keep any size: they press with closed
fingers or hook the far face.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.geometry import held_span, is_held, release_frame
from warpskill.nouns.typical import is_open_topped
from warpskill.robot.grasps import FIT_MARGIN, rim_fits
from warpskill.robot.model import MAX_OPENING

__all__ = ["DESCENT_SPEED", "SUBSTITUTE_WIDTH", "USABLE_OPENING", "clear_path", "fit_sizes", "held_by_rim",
           "needs_substitute", "rest_until", "resting_axis", "upright"]

USABLE_OPENING = MAX_OPENING - FIT_MARGIN
"""[m] widest object edge the gripper closes on."""

SUBSTITUTE_WIDTH = USABLE_OPENING - 0.01
"""[m] horizontal extents of a substitute object (the usable opening less a margin)."""

DESCENT_SPEED = 0.5
"""[m/s] fastest descent of a held object in the robot's version of the demonstration."""


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


def upright(rot: np.ndarray, up: int | None = None) -> np.ndarray:
    """(F, 3, 3) the rotations ``rot`` turned so that the cuboid rests on a face, heading kept.

    The cuboid axis ``up`` (default: each frame's axis nearest the world's vertical) becomes
    vertical and the next axis keeps its horizontal direction. A cuboid can only rest on a
    face; a reconstruction's tilt, however slight, stands it on an edge, from which a tall
    one falls in the replay before the robot reaches it (a 53 cm pillar tilted 5 degrees
    toppled in Newton).
    """
    out = np.array(rot, dtype=float, copy=True)
    for f, R in enumerate(rot):
        i = int(np.argmax(np.abs(R[2]))) if up is None else up
        j, k = (i + 1) % 3, (i + 2) % 3
        col_i = np.array([0.0, 0.0, math.copysign(1.0, R[2, i])])
        col_j = R[:, j] - (R[:, j] @ col_i) * col_i
        if np.linalg.norm(col_j) < 1e-9:  # axis j is vertical (only where ``up`` is given)
            col_j = R[:, k] - (R[:, k] @ col_i) * col_i
            col_j = np.cross(col_j, col_i)
        col_j /= np.linalg.norm(col_j)
        out[f][:, i], out[f][:, j], out[f][:, k] = col_i, col_j, np.cross(col_i, col_j)
    return out


def rest_until(recon: Reconstruction, k: int) -> Reconstruction:
    """``recon`` as the robot performs it when it takes over the object held from frame 0 at frame ``k``.

    Frames 0 to ``k``: the object rests on its support (the table, z = 0, or the top of a
    static box under it) below its frame-``k`` centre, with that frame's heading, on the
    face of :func:`resting_axis` (:func:`upright`); ``grasped`` is 0 before ``k``, so ``k``
    is the grasp onset. Held, it keeps that orientation (the robot carries it so). Its
    centre follows the demonstrated path lowered by the drop onto the support, the drop
    shrinking linearly to 0 at the end of the grasped span (the frame after the last held
    one, or the last frame), but never below the highest support it will still pass over: the
    robot lifts the object onto the demonstrated path and sets it down where the
    demonstration does. The hand path is lowered with it (by the whole drop before ``k``).

    Args:
        recon: a reconstruction with the robot's sizes (:func:`fit_sizes`) whose object is
            held (:func:`~warpskill.geometry.is_held`) in frames 0 and ``k``.
        k: the grasp onset, a frame of the grasped span.
    """
    end = release_frame(recon.grasped)
    R = upright(recon.object_rot[k: k + 1], up=resting_axis(recon))[0]
    half = 0.5 * float(np.abs(R[2]) @ recon.object_size)  # [m] vertical half extent
    floor = _support(recon.object_pos[:, :2], 0.5 * min(recon.object_size[:2]), recon.static_pos,
                     recon.static_rot, recon.static_size)  # (F,) [m]
    z = recon.object_pos[:, 2]
    drop = np.zeros(recon.num_frames)  # (F,) [m] how far each frame is lowered
    drop[: k + 1] = z[k] - floor[k] - half
    if end > k:
        ahead = np.maximum.accumulate(floor[end:k:-1])[::-1]  # frames k+1..end: the highest support still ahead
        lowered = z[k + 1: end + 1] - drop[k] * np.linspace(1.0, 0.0, end - k + 1)[1:]
        drop[k + 1: end + 1] = z[k + 1: end + 1] - np.maximum(lowered, ahead + half)
    object_pos = recon.object_pos.copy()
    object_pos[: k + 1] = recon.object_pos[k]
    object_pos[:, 2] -= drop
    object_rot = recon.object_rot.copy()
    object_rot[: end + 1] = R
    hand_pos = recon.hand_pos.copy()
    hand_pos[:, 2] -= drop
    grasped = recon.grasped.copy()
    grasped[:k] = 0.0
    return dataclasses.replace(recon, object_pos=object_pos, object_rot=object_rot, hand_pos=hand_pos,
                               grasped=grasped)


def clear_path(recon: Reconstruction) -> Reconstruction:
    """``recon`` with a held object's path the robot can follow: never inside its support, no steps down.

    From the grasp onset to the release frame, the object's centre is raised where needed:
    to rest on its support (the table or a static top under it) instead of sinking into it
    (a reconstruction's contacts are soft, the robot's object is not, and a grasp pose on a
    sunk object lies below the held poses that follow it), and so that it descends no faster
    than :data:`DESCENT_SPEED` (where the support under a carried object drops away, as it
    leaves a static box's top, the path would otherwise step down within a frame, which no
    slow-down of the replay makes trackable). The hand rises with the object it holds.
    """
    held = held_span(recon.grasped)
    if held is None:
        return recon
    span = slice(held[0], release_frame(recon.grasped) + 1)
    floor = _support(recon.object_pos[span, :2], 0.5 * min(recon.object_size[:2]), recon.static_pos,
                     recon.static_rot, recon.static_size)
    half = 0.5 * np.abs(recon.object_rot[span, 2, :]) @ recon.object_size
    z = np.maximum(recon.object_pos[span, 2], floor + half)  # (span,) [m]
    steps = np.diff(recon.t[span])
    for j in range(1, len(z)):
        z[j] = max(z[j], z[j - 1] - DESCENT_SPEED * float(steps[j - 1]))
    rise = z - recon.object_pos[span, 2]
    if not np.any(rise > 0):
        return recon
    object_pos, hand_pos = recon.object_pos.copy(), recon.hand_pos.copy()
    object_pos[span, 2] = z
    hand_pos[span, 2] += rise
    return dataclasses.replace(recon, object_pos=object_pos, hand_pos=hand_pos)


def _onset(recon: Reconstruction) -> int:
    span = held_span(recon.grasped)
    return 0 if span is None else span[0]


def _still_until_onset(recon: Reconstruction) -> Reconstruction:
    """``recon`` with the object at its onset place and rotation in every frame before the grasp onset.

    Nothing moves an object over the table before the hand touches it: a reconstruction's
    drift there (a 6 cm slide of an untouched object) would leave the robot's grasp where the
    object is not. Its height stays each frame's own (an object settling onto its support).
    """
    k = _onset(recon)
    if k == 0:
        return recon
    object_pos, object_rot = recon.object_pos.copy(), recon.object_rot.copy()
    object_pos[:k, :2], object_rot[:k] = object_pos[k, :2], object_rot[k]
    return dataclasses.replace(recon, object_pos=object_pos, object_rot=object_rot)


def resting_axis(recon: Reconstruction) -> int:
    """The cuboid axis (0, 1 or 2) that is vertical while the object rests before the grasp.

    The axis nearest the world's vertical at the grasp onset; for an object held from the
    first frame (carried into view, never seen resting), the one nearest it in most frames
    (a carried object's reconstructed tilt is unreliable).
    """
    nearest = np.argmax(np.abs(recon.object_rot[:, 2, :]), axis=1)  # (F,)
    if is_held(recon.grasped[0]):
        return int(np.argmax(np.bincount(nearest, minlength=3)))
    return int(nearest[_onset(recon)])


def _too_wide(recon: Reconstruction, size: np.ndarray) -> bool:
    """Whether a grasp action's cuboid of ``size`` is wider than the usable opening on every face."""
    if str(recon.action).startswith(("push_", "pull_")):
        return False
    up = resting_axis(recon)
    return bool(all(size[i] > USABLE_OPENING for i in range(3) if i != up))


def held_by_rim(recon: Reconstruction, size: np.ndarray) -> bool:
    """Whether a grasp action's cuboid of ``size``, too wide for any face, is an open vessel whose rim fits."""
    return (_too_wide(recon, size) and is_open_topped(str(recon.object_noun))
            and rim_fits(float(size[resting_axis(recon)])))


def needs_substitute(recon: Reconstruction, size: np.ndarray) -> bool:
    """Whether a grasp action's cuboid of ``size`` fits the gripper neither on a face nor by its rim."""
    return _too_wide(recon, size) and not held_by_rim(recon, size)


def _edges(size: np.ndarray) -> str:
    """``size`` (3,) [m] as ``0.084 x 0.093 x 0.104``."""
    return " x ".join(f"{s:.3f}" for s in size)


def _no_rim(recon: Reconstruction, size: np.ndarray) -> str:
    """Why a cuboid too wide for every face is not held by its rim either (for the substitution's note)."""
    if not is_open_topped(str(recon.object_noun)):
        return f" and no rim to hold (the {recon.object_noun or 'unnamed object'} is no open vessel)"
    return f" and its {size[resting_axis(recon)]:.3f} m wall is too low for a rim grasp"


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
    if held_by_rim(recon, size):
        notes.append(f"object: the {_edges(size)} m {recon.object_noun} is wider than the gripper's "
                     f"{USABLE_OPENING:.3f} m usable opening on every face: the robot holds it by its rim")
    if not keep_size and needs_substitute(recon, size):
        up = resting_axis(recon)
        old = size.copy()
        size = np.array([s if i == up else min(s, SUBSTITUTE_WIDTH) for i, s in enumerate(size)])
        notes.append(f"object: the {_edges(old)} m cuboid is wider than the gripper's {USABLE_OPENING:.3f} m "
                     f"usable opening on every face{_no_rim(recon, old)}: the robot handles a {_edges(size)} m "
                     "substitute (height kept; --keep-size refuses instead)")
    given, recon = recon, _still_until_onset(recon)
    rot = recon.object_rot.copy()  # resting until the contact: it must rest on a face (later tilts are noise)
    rot[: _onset(recon) + 1] = upright(recon.object_rot[: _onset(recon) + 1])
    unchanged = (np.allclose(size, given.object_size) and np.allclose(statics, given.static_size)
                 and np.allclose(recon.object_pos, given.object_pos, atol=1e-9)
                 and np.allclose(rot, given.object_rot, atol=1e-9))
    if unchanged:
        return given, "; ".join(notes)
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
    span = held_span(recon.grasped)
    if span is not None:
        a, b = span[0], release_frame(recon.grasped)
        if b > a:
            ds[a:b + 1] = np.interp(np.arange(a, b + 1), [a, b], [ds[a], ds[b]])
    object_pos = recon.object_pos.copy()
    object_pos[:, 2] += half_new - half_old + ds
    fitted = dataclasses.replace(recon, object_size=size, object_pos=object_pos, object_rot=rot,
                                 static_pos=static_pos, static_size=statics)
    return fitted, "; ".join(notes)
