"""Stage (a)'s first scene, read off the masks' geometry before any optimisation.

The hand's apparent width (its radius is known; :func:`~warpskill.optimizer.measurements.hand_depth`)
gives the scene's depth; with the prior elevation, the object's box bottom at that depth
gives the camera height. Cuboids stand upright on the ground below their mask's bottom
edge; the hand's tip is at the hand pixel nearest the object, at the object's depth. A long
object (a fork, a pen: its noun's typical width several times its depth) lies instead along
its box's diagonal on the ground, in its noun's proportions.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
import torch

from warpskill.contract.camera import Intrinsics
from warpskill.engine.projection import camera_rotation
from warpskill.engine.rotations import yaw_rotation
from warpskill.geometry import frame_from_axis
from warpskill.optimizer.measurements import TYPICAL_HAND_TILT, MaskGeometry, fill_missing, hand_depth
from warpskill.optimizer.measurements import hand_tilt as measured_hand_tilt
from warpskill.optimizer.scene import MIN_STATIC_SIZE, SceneTrajectories, static_poses
from warpskill.optimizer.weights import LossWeights


class ObjectDepth(str, enum.Enum):
    """Where the object is after it was first seen (see :func:`initial_guess`): it keeps its
    resting depth, stands on the ground below its mask's bottom edge, or (only in the frames
    :func:`warpskill.optimizer.inputs.rests_on_static` finds) on the static box's top or on
    the ground behind the box."""

    RESTING = "resting depth"
    GROUND = "on the ground"
    STATIC = "on the static"
    BEHIND = "behind the static"

    @property
    def placed(self) -> bool:
        """Whether this is a placement against the first static box (its top or its back)."""
        return self in (ObjectDepth.STATIC, ObjectDepth.BEHIND)

INITIAL_CAMERA_ELEVATION = 0.6  # [rad] the camera's look below the horizon, a person's view of a table
CAMERA_HEIGHT_RANGE = (0.15, 1.5)  # [m] the camera heights a first guess may take: a table's scale
MAX_RAY_DEPTH = 3.0  # [m] camera depth at which a ray that meets the ground farther away (or never) stops
MIN_RAY_DESCENT = 1e-3  # a ray's downward slope (z per unit depth) below which it counts as never reaching a plane
FRONT_FACE_SHARE = 0.6  # share of an upright cuboid's box height that is its front face (above it: its top)
CUBOID_HEIGHT_RANGE = (0.03, 0.4)  # [m] the heights a first guess may give a cuboid
CUBOID_SIZE_RANGE = (0.03, 0.5)  # [m] the sizes a first guess may give a cuboid, each axis
MIN_LONG_SIZE = 0.015  # [m] a long object's smallest first edge: above the size floor, where its gradient is alive
BEHIND_GAP = 0.01  # [m] between the static box's back and an object placed behind it, in a first guess
APPROACH_GROWTH = 1.25  # a carried cuboid's box this much wider than at first: it has come closer
LONG_ASPECT = 2.5  # a typical width this many times the typical depth makes a noun long (its start lies turned)


@dataclass
class GuessCamera:
    """The first guess's camera: intrinsics ``K`` (3, 3) at the masks' resolution, rotation
    ``R_wc`` (3, 3) camera to world, centre ``position`` (3,) [m] above the world origin,
    and the image width ``width`` [px]."""

    K: np.ndarray
    R_wc: np.ndarray
    position: np.ndarray
    width: int

    def rays(self, pixels: np.ndarray) -> np.ndarray:
        """World directions (M, 3) of the rays through pixels (M, 2) [px], of unit camera depth."""
        K = self.K
        d = np.stack([(pixels[:, 0] - K[0, 2]) / K[0, 0], (pixels[:, 1] - K[1, 2]) / K[1, 1], np.ones(len(pixels))], -1)
        return d @ self.R_wc.T

    def ray(self, pixel: np.ndarray) -> np.ndarray:
        """World direction (3,) of the ray through one pixel (2,) [px], of unit camera depth."""
        return self.rays(pixel[None])[0]

    def plane_point(self, pixel: np.ndarray, height: float) -> tuple[np.ndarray, float]:
        """Where the ray through ``pixel`` (2,) [px] meets the horizontal plane at ``height`` [m]
        (at most :data:`MAX_RAY_DEPTH` away; at unit depth when it never descends to it): the
        world point (3,) [m] and its camera depth [m]."""
        ray = self.ray(pixel)
        t = (height - self.position[2]) / ray[2] if ray[2] < -MIN_RAY_DESCENT else 1.0
        t = min(t, MAX_RAY_DEPTH)
        return self.position + t * ray, t


def initial_guess(
    targets: np.ndarray,
    contact: np.ndarray,
    intrinsics: Intrinsics,
    num_static: int,
    *,
    object_depth: ObjectDepth | str = ObjectDepth.RESTING,
    resting: np.ndarray | None = None,
    hand_width: bool = True,
    carried: np.ndarray | None = None,
    hand_tilt: bool = True,
    typical_camera_height: float = LossWeights.typical_camera_height,
    object_shape: tuple[float, float, float] | None = None,
) -> SceneTrajectories:
    """A rough scene read off the masks' geometry, before any optimisation.

    Where the object is after it was first seen is ambiguous from one frame's mask (the
    paper's Fig. 1: on top of a box, or behind it on the ground), so ``object_depth``
    names the hypothesis: it keeps its ``"resting depth"``, or stands ``"on the ground"``
    below its mask's bottom edge in every frame, or, in the ``resting`` frames after the
    release, stands ``"on the static"`` box's top, the box reaching back (or forward) under it,
    or on the ground ``"behind the static"`` box, the box ending in front of it and as tall as
    its box's top edge says (one view cannot tell a flat deep box with the object on top from
    a tall thin one with the object behind).

    Args:
        targets: (N, 2 + K, h, w) masks at the working resolution.
        contact: (N,) bool.
        intrinsics: working-resolution intrinsics.
        num_static: K.
        object_depth: an :class:`ObjectDepth` (or its value).
        resting: (N,) bool, the frames where the object may rest on the first static box
            (needed by ``"on the static"`` and ``"behind the static"``).
        hand_width: whether the hand mask's width measures its depth (not so for masks
            drawn from boxes); without it the camera starts at ``typical_camera_height``.
        carried: (N,) bool, frames in which the object may be in the hand (default: ``contact``).
        hand_tilt: read the hand's lean towards the camera off its foreshortening (with
            ``hand_width``; :func:`~warpskill.optimizer.measurements.hand_tilt`), else start
            it at a typical forearm's.
        typical_camera_height: [m] the camera height where the masks give none
            (:attr:`LossWeights.typical_camera_height`).
        object_shape: the object's typical (height, width, depth) [m] by its noun: a long one
            (:data:`LONG_ASPECT`) starts lying along its box's diagonal at its typical length,
            the scene scaled to match (:func:`_long_object`). None: upright, no yaw.

    Raises:
        ValueError: an unknown ``object_depth``, or a placement against the static without a static box
            or resting frames.
    """
    if object_depth not in {depth.value for depth in ObjectDepth}:
        raise ValueError(f"object_depth must be one of {[depth.value for depth in ObjectDepth]}, not {object_depth!r}")
    object_depth = ObjectDepth(object_depth)
    carried = np.asarray(contact if carried is None else carried, dtype=bool)
    if object_depth.placed and (num_static == 0 or resting is None or not np.any(resting)):
        raise ValueError(f"object_depth {object_depth.value!r} needs a static box and frames where the object rests "
                         "against it")
    K = intrinsics.K
    R_wc = camera_rotation(torch.tensor(INITIAL_CAMERA_ELEVATION, dtype=torch.float64)).numpy()
    hand_geom = MaskGeometry(targets[:, 0])
    object_geom = MaskGeometry(targets[:, 1])
    object_centroid = fill_missing(object_geom.centroid, object_geom.visible)
    depth = hand_depth(hand_geom, object_centroid, K) if hand_width else None
    height = typical_camera_height if depth is None else _camera_height(depth, object_geom, carried, K, R_wc)
    camera = GuessCamera(K, R_wc, np.array([0.0, 0.0, height]), targets.shape[-1])

    on_ground = object_depth in (ObjectDepth.GROUND, ObjectDepth.BEHIND)
    object_pos, object_size, _ = _cuboid_from_masks(object_geom, camera, carried, on_ground)
    lying = _long_object(object_pos, object_size, object_shape, object_geom, hand_geom, camera, carried,
                         np.asarray(contact, bool))
    object_pos, object_size, object_yaw, ruler = lying or (object_pos, object_size, 0.0, 1.0)
    static_pos, static_size, static_top = [], [], []
    for j in range(num_static):
        static_geom = MaskGeometry(targets[:, 2 + j])
        pos, size, visible = _cuboid_from_masks(static_geom, camera, carried, True)
        first = np.flatnonzero(visible)[0]
        static_pos.append(pos[first])
        static_size.append(size)
        static_top.append(np.array([0.5 * (static_geom.box[first, 0] + static_geom.box[first, 2]),
                                    static_geom.box[first, 1]]))
    if object_depth is ObjectDepth.STATIC:
        object_pos, static_pos[0], static_size[0] = _placed_on_static(
            object_pos, object_size, object_geom, np.asarray(contact, bool), resting, static_pos[0], static_size[0],
            camera)
    elif object_depth is ObjectDepth.BEHIND:
        object_pos, static_pos[0], static_size[0] = _placed_behind_static(
            object_pos, object_size, object_geom, np.asarray(contact, bool), resting, static_pos[0], static_size[0],
            static_top[0], camera)
    toward = measured_hand_tilt(hand_geom, K) if hand_width and hand_tilt else None
    hand_pos, hand_rot = _hand_poses(hand_geom, object_centroid, object_pos, camera,
                                     TYPICAL_HAND_TILT if toward is None else toward)
    return _scene(ruler * hand_pos, hand_rot, ruler * object_pos, ruler * object_size, object_yaw,
                  [ruler * pos for pos in static_pos], [ruler * size for size in static_size], ruler * height)


def _camera_height(depth: float, object_geom: MaskGeometry, carried: np.ndarray, K: np.ndarray,
                   R_wc: np.ndarray) -> float:
    """The camera height [m] that puts the object's box bottom on the ground at camera depth
    ``depth`` [m], within :data:`CAMERA_HEIGHT_RANGE`.

    The bottom row is the median over the frames before the object is first ``carried``
    (a lifted object's box bottom is no ground row: it would put the camera too low, the
    scene too small), or over all frames when it is not seen before.
    """
    onset = np.flatnonzero(carried)
    standing = object_geom.box[: onset[0] if len(onset) else len(carried), 3]
    bottom_row = np.nanmedian(standing if np.isfinite(standing).any() else object_geom.box[:, 3])
    ray = np.array([0.0, (bottom_row - K[1, 2]) / K[1, 1], 1.0])
    return float(np.clip(depth * (ray @ R_wc.T) @ np.array([0.0, 0.0, -1.0]), *CAMERA_HEIGHT_RANGE))


def _cuboid_from_masks(
    geom: MaskGeometry, camera: GuessCamera, carried: np.ndarray, on_ground: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame centres (N, 3) [m], a size (3,) [m] and visibility (N,) of an upright cuboid
    seen in ``geom``.

    Where it is first seen the cuboid stands on the ground below its mask's bottom edge;
    later it stands there again (``on_ground``) or keeps that camera depth. While it is
    ``carried`` (N,), a box much wider than where first seen whole across says it has come
    closer (size constancy; its bottom edge may be the image's border): its depth shrinks
    in proportion, along the ray through the box's centre.
    """
    K, N = camera.K, len(geom.visible)
    visible = np.flatnonzero(geom.visible)
    u0, v0, u1, v1 = geom.box[visible[0]]
    _, rest_depth = camera.plane_point(np.array([0.5 * (u0 + u1), v1]), 0.0)
    # Its width where first seen whole across (a box cut by a side border is no measure).
    across = visible[(geom.box[visible, 0] > 0) & (geom.box[visible, 2] < camera.width)]
    rest_width = geom.box[across[0], 2] - geom.box[across[0], 0] if len(across) else np.inf
    pos = np.zeros((N, 3))
    sizes = []
    for k in visible:
        u0, v0, u1, v1 = geom.box[k]
        bottom_pixel = np.array([0.5 * (u0 + u1), v1])
        bottom, depth = camera.plane_point(bottom_pixel, 0.0)
        if not on_ground:
            depth = rest_depth
            bottom = camera.position + depth * camera.ray(bottom_pixel)
        width = (u1 - u0) * depth / K[0, 0]
        height = np.clip((v1 - v0) * depth / K[1, 1] * FRONT_FACE_SHARE, *CUBOID_HEIGHT_RANGE)
        if carried[k] and u0 > 0 and u1 < camera.width and u1 - u0 > APPROACH_GROWTH * rest_width:
            depth = rest_depth * rest_width / (u1 - u0)
            pos[k] = camera.position + depth * camera.ray(np.array([0.5 * (u0 + u1), 0.5 * (v0 + v1)]))
            continue
        sizes.append([width, width, height])
        pos[k] = bottom + np.array([0.0, 0.5 * width, 0.5 * height])
    size = np.clip(np.median(np.array(sizes), 0), *CUBOID_SIZE_RANGE)
    return fill_missing(pos, geom.visible), size, np.asarray(geom.visible)


def lying_along_box(ground: tuple[float, float], shape: tuple[float, float, float]) -> tuple[np.ndarray, float]:
    """Size (3,) [m] and yaw [rad, 0..pi/2] of an object of ``shape``'s proportions (height,
    width, depth) lying flat whose footprint spans ``ground`` = (across, along) [m], its box's
    extents on the ground across and along the view.

    A thin rectangle of length L and width w = L / a (a = width / depth) turned by yaw spans
    ``L cos + w sin`` across and ``L sin + w cos`` along; their ratio r gives
    ``tan(yaw) = (a - r) / (r a - 1)``: 0 for a box at least a times wider than deep, pi/2 for
    one at least a times deeper than wide. The length comes from the extent across, measured
    at the box's bottom edge: the extent along also holds the object's height and, near the
    horizon, grows without bound. Boxes do not tell the two diagonals apart: the caller picks
    the sign.
    """
    across, along = ground
    aspect = shape[1] / shape[2]
    ratio = across / along
    yaw = float(np.clip(np.arctan2(aspect - ratio, ratio * aspect - 1), 0.0, np.pi / 2))
    length = across / (np.cos(yaw) + np.sin(yaw) / aspect)
    return np.array([length, length / aspect, length * shape[0] / shape[1]]), yaw


def _long_object(
    pos: np.ndarray, size: np.ndarray, shape: tuple[float, float, float] | None, geom: MaskGeometry, hand: MaskGeometry,
    camera: GuessCamera, carried: np.ndarray, contact: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """A long object's centres (N, 3), size (3,) [m] and yaw [rad] lying along its box's
    diagonal (:func:`lying_along_box`), from the boxes' ground extents where it rests whole in
    view, and the scale (the ruler) that gives it its typical length, ``shape[1]``: the whole
    scene scaled about the camera's foot (the view unchanged), the camera kept within
    :data:`CAMERA_HEIGHT_RANGE`; None for a shape that is not long (width under
    :data:`LONG_ASPECT` times depth, or no shape) or an object never at rest whole in view (the
    upright cuboid ``pos``, ``size`` stays). The diagonal is the one the hand touches: a hand
    below and right of the object's centre (or above and left) holds one end of a box-wide
    object running from top left to bottom right.
    """
    if shape is None or shape[1] < LONG_ASPECT * shape[2]:
        return None
    ground = _ground_extent(geom, camera, ~carried, height=0.0)
    if ground is None:
        return None
    new_size, yaw = lying_along_box(ground, shape)
    ground = _ground_extent(geom, camera, ~carried, height=float(new_size[2])) or ground  # the far edge is the top's
    new_size, yaw = lying_along_box(ground, shape)
    touched = contact & geom.visible & hand.visible
    if touched.any():
        du, dv = np.median(hand.centroid[touched] - geom.centroid[touched], 0)
        yaw = -yaw if du * dv > 0 else yaw
    along = abs(np.sin(yaw)) * new_size[0] + np.cos(yaw) * new_size[1]
    shift = np.array([0.0, 0.5 * (along - size[1]), 0.5 * (new_size[2] - size[2])])
    ruler = float(np.clip(shape[1] / new_size[0], *np.divide(CAMERA_HEIGHT_RANGE, camera.position[2])))
    return pos + shift, np.clip(ruler * new_size, MIN_LONG_SIZE, CUBOID_SIZE_RANGE[1]) / ruler, yaw, ruler


def _ground_extent(geom: MaskGeometry, camera: GuessCamera, frames: np.ndarray,
                   height: float) -> tuple[float, float] | None:
    """Median (across, along) [m] of the object's boxes on the ground in ``frames`` (N,) where
    the box is whole in view: across at the bottom edge's depth, along from the bottom edge on
    the ground to the top edge on the plane at ``height`` [m]; None without such a frame."""
    K = camera.K
    whole = geom.visible & (geom.box[:, 0] > 0) & (geom.box[:, 1] > 0) & (geom.box[:, 2] < camera.width)
    spans = []
    for k in np.flatnonzero(whole & frames):
        u0, v0, u1, v1 = geom.box[k]
        near, depth = camera.plane_point(np.array([0.5 * (u0 + u1), v1]), 0.0)
        far, _ = camera.plane_point(np.array([0.5 * (u0 + u1), v0]), height)
        if far[1] > near[1]:
            spans.append(((u1 - u0) * depth / K[0, 0], far[1] - near[1]))
    return tuple(np.median(spans, 0)) if spans else None


def _placed_on_static(
    object_pos: np.ndarray, object_size: np.ndarray, geom: MaskGeometry, contact: np.ndarray, resting: np.ndarray,
    static_pos: np.ndarray, static_size: np.ndarray, camera: GuessCamera,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Object centres (N, 3) [m] that stand on the static box's top in the ``resting`` frames,
    below the mask's bottom edge, and are carried there during the contact (their camera
    depth moving from where the object started to where it rests); and the static box's
    centre (3,) and size (3,) [m] widened to reach under the object."""
    offset = np.array([0.0, 0.5 * object_size[1], 0.5 * object_size[2]])
    pos = object_pos.copy()
    for k in np.flatnonzero(resting & geom.visible):
        pos[k] = camera.plane_point(_bottom_pixel(geom, k), static_size[2])[0] + offset
    pos, rest = _carried_to_rest(pos, offset, geom, contact, resting, camera)
    lo = np.minimum(static_pos[:2] - 0.5 * static_size[:2], rest[:2] - 0.5 * object_size[:2])
    hi = np.maximum(static_pos[:2] + 0.5 * static_size[:2], rest[:2] + 0.5 * object_size[:2])
    widened_pos, widened_size = static_pos.copy(), static_size.copy()
    widened_pos[:2], widened_size[:2] = 0.5 * (lo + hi), hi - lo
    return pos, widened_pos, widened_size


def _placed_behind_static(
    object_pos: np.ndarray, object_size: np.ndarray, geom: MaskGeometry, contact: np.ndarray, resting: np.ndarray,
    static_pos: np.ndarray, static_size: np.ndarray, static_top: np.ndarray, camera: GuessCamera,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Object centres (N, 3) [m] on the ground behind the static box in the ``resting`` frames
    (below the mask's bottom edge, at least :data:`BEHIND_GAP` past the box's front plus
    :data:`~warpskill.optimizer.scene.MIN_STATIC_SIZE`), carried there during the contact; and
    the static box's centre (3,) and size (3,) [m] ending :data:`BEHIND_GAP` in front of the
    object, as tall as its box's top edge ``static_top`` (2,) [px, the edge's middle] puts
    its back's top edge."""
    pos = object_pos.copy()
    front = static_pos[1] - 0.5 * static_size[1]
    nearest = front + MIN_STATIC_SIZE + BEHIND_GAP + 0.5 * object_size[1]  # the object's least centre depth
    placed = np.flatnonzero(resting)
    pos[placed, 1] = np.maximum(pos[placed, 1], nearest)
    offset = np.array([0.0, 0.5 * object_size[1], 0.5 * object_size[2]])
    pos, rest = _carried_to_rest(pos, offset, geom, contact, resting, camera)
    back = rest[1] - 0.5 * object_size[1] - BEHIND_GAP
    ray = camera.ray(static_top)
    top = camera.position[2] + (back - camera.position[1]) / max(ray[1], MIN_RAY_DESCENT) * ray[2]
    size = static_size.copy()
    size[1] = back - front
    size[2] = float(np.clip(top, *CUBOID_HEIGHT_RANGE))
    centre = np.array([static_pos[0], 0.5 * (front + back), 0.5 * size[2]])
    return pos, centre, size


def _bottom_pixel(geom: MaskGeometry, k: int) -> np.ndarray:
    """The middle (2,) [px] of frame ``k``'s mask box's bottom edge."""
    u0, _, u1, v1 = geom.box[k]
    return np.array([0.5 * (u0 + u1), v1])


def _carried_to_rest(
    pos: np.ndarray, offset: np.ndarray, geom: MaskGeometry, contact: np.ndarray, resting: np.ndarray,
    camera: GuessCamera,
) -> tuple[np.ndarray, np.ndarray]:
    """Object centres (N, 3) [m] from ``pos``: the ``resting`` frames where the mask is gone at
    the mean rest of those where it shows, and during the ``contact`` each visible frame on its
    bottom pixel's ray, its camera depth moving from where the object started to where it
    rests (``offset`` (3,) [m]: from the bottom's middle to the centre). Returns them and the rest (3,)."""
    pos = pos.copy()
    rest = pos[resting & geom.visible].mean(0) if (resting & geom.visible).any() else pos[resting].mean(0)
    pos[resting & ~geom.visible] = rest
    held = np.flatnonzero(contact)
    if len(held) > 1:
        depth = lambda p: float((p - camera.position) @ camera.R_wc[:, 2])  # noqa: E731
        start, end = depth(pos[held[0]] - offset), depth(rest - offset)
        for k in held[geom.visible[held]]:
            share = (k - held[0]) / (held[-1] + 1 - held[0])
            pos[k] = camera.position + ((1 - share) * start + share * end) * camera.ray(_bottom_pixel(geom, k)) + offset
    return pos, rest


def _hand_poses(
    geom: MaskGeometry, object_centroid: np.ndarray, object_pos: np.ndarray, camera: GuessCamera, toward: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Hand tip positions (N, 3) [m] and rotations (N, 3, 3): the tip at the hand pixel
    nearest the object's centroid (N, 2) [px], at the object's camera depth, the axis pointing
    from there towards the rest of the hand mask and, by the lean ``toward`` (the sine of its
    angle out of the image plane), towards the camera."""
    N = len(geom.visible)
    hand_pos = np.zeros((N, 3))
    hand_axis = np.zeros((N, 3))
    for k in np.flatnonzero(geom.visible):
        pixels = geom.pixels(k)
        tip = pixels[np.argmin(((pixels - object_centroid[k]) ** 2).sum(1))]
        tip_depth = ((object_pos[k] - camera.position) @ camera.R_wc)[2]
        hand_pos[k] = camera.position + tip_depth * camera.ray(tip)
        arm = geom.centroid[k] - tip
        arm = arm / np.linalg.norm(arm) if np.linalg.norm(arm) > 1e-6 else np.array([0.0, 1.0])
        hand_axis[k] = camera.R_wc @ np.array([*(np.sqrt(1.0 - toward**2) * arm), -toward])
    return fill_missing(hand_pos, geom.visible), frame_from_axis(fill_missing(hand_axis, geom.visible))


def _scene(
    hand_pos: np.ndarray, hand_rot: np.ndarray, object_pos: np.ndarray, object_size: np.ndarray, object_yaw: float,
    static_pos: list[np.ndarray], static_size: list[np.ndarray], camera_height: float,
) -> SceneTrajectories:
    """The guessed scene in float32 tensors: the object upright at ``object_yaw`` [rad], the
    static boxes on the ground with no yaw, the camera at ``camera_height`` [m] and
    :data:`INITIAL_CAMERA_ELEVATION`."""
    f = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
    N, num_static = len(hand_pos), len(static_pos)
    static_size_t = f(np.reshape(static_size, (num_static, 3)))
    static_xy = f(np.reshape(static_pos, (num_static, 3))[:, :2])
    s_pos, s_rot = static_poses(static_xy, torch.zeros(num_static), static_size_t)
    return SceneTrajectories(
        hand_pos=f(hand_pos),
        hand_rot=f(hand_rot),
        object_pos=f(object_pos),
        object_rot=yaw_rotation(torch.full((N,), object_yaw)),
        object_size=f(object_size),
        static_pos=s_pos,
        static_rot=s_rot,
        static_size=static_size_t,
        camera_height=torch.tensor(camera_height),
        camera_elevation=torch.tensor(INITIAL_CAMERA_ELEVATION),
    )
