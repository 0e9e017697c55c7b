"""Stage (a) of the optimisation: a physics-free fit of per-frame poses to the masks.

Per frame it places the hand and the object freely (no dynamics), together with the object
size, the static cuboids and the camera's height and elevation, minimising the perceptual
dIoU, the hand-tip-to-object distance in contact frames and a smoothness prior. The result
is a first camera and first trajectories for the physics stage (:mod:`warpskill.optimize`).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from warpskill.contract.camera import Intrinsics
from warpskill.contract.geometry import frame_from_axis
from warpskill.engine.distances import (
    box_signed_distance,
    lowest_corner_height,
    support_height,
)
from warpskill.engine.primitives import HAND_LENGTH, HAND_RADIUS
from warpskill.engine.projection import camera_rotation
from warpskill.engine.rotations import rotation_from_6d, rotation_to_6d, yaw_rotation
from warpskill.optimizer.known import measured, pin_sizes
from warpskill.optimizer.losses import MaskTargets
from warpskill.optimizer.scene import (
    SceneTrajectories,
    perceptual_loss,
    positive,
    positive_inverse,
    scene_priors,
    static_poses,
)
from warpskill.optimizer.weights import LossWeights

MIN_OBJECT_SIZE = 0.01  # [m]
MIN_STATIC_SIZE = 0.02  # [m]
INITIAL_CAMERA_HEIGHT = 0.45  # [m]
INITIAL_CAMERA_ELEVATION = 0.6  # [rad]
FREE_MARGIN_FRAMES = 2  # frames next to a contact frame that the resting priors ignore
TYPICAL_HAND_TILT = 1.0 / math.sqrt(5.0)  # a forearm's lean towards the camera (sin of 27 deg out of the image plane)
APPROACH_GROWTH = 1.25  # a carried cuboid's box this much wider than at first: it has come closer


class _MaskGeometry:
    """Per-frame 2D statistics of target masks (N, h, w) in [0, 1]: visibility, centroid, box."""

    def __init__(self, masks: np.ndarray):
        hard = masks > 0.5
        self.visible = hard.reshape(len(masks), -1).any(1)
        h, w = masks.shape[1:]
        self.centroid = np.full((len(masks), 2), np.nan)
        self.box = np.full((len(masks), 4), np.nan)
        for k in np.flatnonzero(self.visible):
            rows, cols = np.nonzero(hard[k])
            self.centroid[k] = cols.mean() + 0.5, rows.mean() + 0.5
            self.box[k] = cols.min(), rows.min(), cols.max() + 1.0, rows.max() + 1.0
        self._hard = hard

    def pixels(self, k: int) -> np.ndarray:
        """(M, 2) pixel centres (u, v) of frame k's mask."""
        rows, cols = np.nonzero(self._hard[k])
        return np.stack([cols + 0.5, rows + 0.5], -1)


def _fill_missing(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Copy each invalid frame's value from the nearest valid frame."""
    idx = np.flatnonzero(valid)
    if len(idx) == 0:
        raise ValueError("no valid frame to initialise from")
    nearest = idx[np.abs(np.arange(len(values))[:, None] - idx[None]).argmin(1)]
    return values[nearest]


def _rays(pixels: np.ndarray, K: np.ndarray, R_wc: np.ndarray) -> np.ndarray:
    """World directions (M, 3) of the camera rays through pixels (M, 2); unit depth."""
    d = np.stack([(pixels[:, 0] - K[0, 2]) / K[0, 0], (pixels[:, 1] - K[1, 2]) / K[1, 1], np.ones(len(pixels))], -1)
    return d @ R_wc.T


def _band_width(points: np.ndarray, axis: np.ndarray) -> float:
    """Width of a band of points (M, 2) along ``axis`` (2,): sqrt(12) x their std (a uniform
    band's width, in the points' units)."""
    return float(np.sqrt(12.0 * np.var(points @ axis)))


def _hand_bands(geom: _MaskGeometry, K: np.ndarray):
    """Per frame whose hand mask holds at least 6 pixels: ``(k, pixels, points, width, across,
    main, thinnest)``: its pixel centres (M, 2) [px], the same in normalised image coordinates
    (over the focal lengths: pixels need not be square), the band's width across its main axis
    (sqrt(12) x the smaller principal std), the unit axes (2,) across and along the band, and
    one pixel's width in those coordinates (the least width to read)."""
    focal = np.array([K[0, 0], K[1, 1]])
    for k in np.flatnonzero(geom.visible):
        pixels = geom.pixels(k)
        if len(pixels) >= 6:
            points = pixels / focal
            variances, axes = np.linalg.eigh(np.cov(points.T))
            across, main = axes.T
            yield k, pixels, points, float(np.sqrt(12.0 * variances[0])), across, main, 1.0 / focal.max()


def _hand_depth(geom: _MaskGeometry, targets_of: np.ndarray, K: np.ndarray) -> float | None:
    """Median camera depth [m] of the hand tip, from the mask's width at the tip.

    The hand is a cylinder of known radius R, so a stretch of mask w wide (in normalised
    image coordinates, pixels over the focal lengths: pixels need not be square) lies at
    depth 2 R / w. Its width is measured across the mask's main axis, in the slab half a width
    long that starts at the tip (the hand pixel nearest ``targets_of`` (N, 2) [px], the
    object's centroid): farther up, a hand reaching forwards or down comes closer to the
    camera and widens.
    """
    depths = []
    for k, pixels, points, width, across, main, thinnest in _hand_bands(geom, K):
        tip = points[np.argmin(((pixels - targets_of[k]) ** 2).sum(1))]
        along = (points - tip) @ main
        along = along if np.median(along) >= 0 else -along  # from the tip up the hand
        slab = points[(along >= 0) & (along <= 0.5 * width)]
        if len(slab) >= 6:
            depths.append(2.0 * HAND_RADIUS / max(_band_width(slab, across), thinnest))
    return float(np.median(depths)) if depths else None


def _hand_tilt(geom: _MaskGeometry, K: np.ndarray) -> float | None:
    """The hand's lean towards the camera (its axis's component along the view: the sine of
    its angle out of the image plane), from its foreshortening: the median over frames of
    sqrt(1 - (L / (5 w))^2), with L and w the mask's length and width (a uniform band's, in
    normalised image coordinates) and 5 the cylinder's length over its diameter, within
    [TYPICAL_HAND_TILT, 0.9]. Perspective lengthens the part nearer the camera, so the lean
    comes out low (0.61 for a true 0.77; 0.3 for a true 0.5 on synthetic pulls): only a
    clearly short hand moves the guess off the typical lean. A hand cut by the border looks
    shorter than it is (hence the upper bound)."""
    leans = []
    for _, _, points, _, across, main, thinnest in _hand_bands(geom, K):
        width = max(_band_width(points, across), thinnest)
        ratio = _band_width(points, main) / (width * HAND_LENGTH / (2.0 * HAND_RADIUS))
        leans.append(np.sqrt(1.0 - min(ratio, 1.0) ** 2))
    return float(np.clip(np.median(leans), TYPICAL_HAND_TILT, 0.9)) if leans else None


OBJECT_DEPTH_HYPOTHESES = ("resting depth", "on the ground", "on the static")
"""Where the object is after it was first seen (see :func:`initial_guess`); the last applies
only to frames that :func:`warpskill.optimizer.inputs.rests_on_static` finds."""


def initial_guess(
    targets: np.ndarray,
    contact: np.ndarray,
    intrinsics: Intrinsics,
    num_static: int,
    *,
    object_depth: str = "resting depth",
    resting: np.ndarray | None = None,
    hand_width: bool = True,
    carried: np.ndarray | None = None,
    hand_tilt: bool = True,
) -> SceneTrajectories:
    """A rough scene read off the masks' geometry, before any optimisation.

    The hand's apparent width (its radius is known) gives the scene's depth; with the
    prior elevation, the object's box bottom at that depth, before it is first carried, gives
    the camera height.
    Cuboids then stand upright on the ground below their mask's bottom edge, sized from
    the mask at that depth; the hand tip is at the hand pixel nearest the object, at the
    object's depth, its axis pointing from there towards the rest of the hand mask and the
    camera.

    Where the object is after it was first seen is ambiguous from one frame's mask (the
    paper's Fig. 1: on top of a box, or behind it on the ground), so ``object_depth``
    names the hypothesis: it keeps its ``"resting depth"``, or stands ``"on the ground"``
    below its mask's bottom edge in every frame, or, in the ``resting`` frames after the
    release, stands ``"on the static"`` box's top, the box reaching back (or forward) under it.

    Args:
        targets: (N, 2 + K, h, w) masks at the working resolution.
        contact: (N,) bool.
        intrinsics: working-resolution intrinsics.
        num_static: K.
        object_depth: one of :data:`OBJECT_DEPTH_HYPOTHESES`.
        resting: (N,) bool, the frames where the object may rest on the first static box
            (needed by ``"on the static"``).
        hand_width: whether the hand mask's width measures its depth (not so for masks
            drawn from boxes); without it the camera starts at its typical height.
        carried: (N,) bool, frames in which the object may be in the hand (default: ``contact``).
        hand_tilt: read the hand's lean towards the camera off its foreshortening (with
            ``hand_width``; :func:`_hand_tilt`), else start it at a typical forearm's.
    """
    if object_depth not in OBJECT_DEPTH_HYPOTHESES:
        raise ValueError(f"object_depth must be one of {OBJECT_DEPTH_HYPOTHESES}, not {object_depth!r}")
    on_static = object_depth == "on the static"
    carried = np.asarray(contact if carried is None else carried, dtype=bool)
    if on_static and (num_static == 0 or resting is None or not np.any(resting)):
        raise ValueError("object_depth 'on the static' needs a static box and frames where the object rests on it")
    N = targets.shape[0]
    K = intrinsics.K
    e0 = INITIAL_CAMERA_ELEVATION
    R_wc = camera_rotation(torch.tensor(e0, dtype=torch.float64)).numpy()
    hand_geom = _MaskGeometry(targets[:, 0])
    object_geom = _MaskGeometry(targets[:, 1])

    object_centroid = _fill_missing(object_geom.centroid, object_geom.visible)
    depth = _hand_depth(hand_geom, object_centroid, K) if hand_width else None
    h0 = INITIAL_CAMERA_HEIGHT
    if depth is not None:
        # The object stands on the ground until it is first carried (a lifted object's box
        # bottom is no ground row: it would put the camera too low, the scene too small).
        onset = np.flatnonzero(carried)
        standing = object_geom.box[: onset[0] if len(onset) else N, 3]
        bottom_row = np.nanmedian(standing if np.isfinite(standing).any() else object_geom.box[:, 3])
        ray = np.array([0.0, (bottom_row - K[1, 2]) / K[1, 1], 1.0])
        h0 = float(np.clip(depth * (ray @ R_wc.T) @ np.array([0.0, 0.0, -1.0]), 0.15, 1.5))
    centre = np.array([0.0, 0.0, h0])

    def ground_point(pixel: np.ndarray) -> tuple[np.ndarray, float]:
        ray = _rays(pixel[None], K, R_wc)[0]
        t = -h0 / ray[2] if ray[2] < -1e-3 else 1.0
        t = min(t, 3.0)
        return centre + t * ray, t  # t is the camera depth (rays have unit z in camera axes)

    h_img, w_img = targets.shape[-2:]

    def cuboid_from_masks(geom: _MaskGeometry, on_ground: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-frame centres, a size and visibility of an upright cuboid seen in ``geom``.

        Where it is first seen the cuboid stands on the ground below its mask's bottom edge;
        later it stands there again (``on_ground``) or keeps that camera depth. While it is
        ``carried``, a box much wider than where first seen whole across says it has come
        closer (size constancy; its bottom edge may be the image's border): its depth shrinks
        in proportion, along the ray through the box's centre.
        """
        visible = np.flatnonzero(geom.visible)
        first = visible[0]
        u0, v0, u1, v1 = geom.box[first]
        _, rest_depth = ground_point(np.array([0.5 * (u0 + u1), v1]))
        # Its width where first seen whole across (a box cut by a side border is no measure).
        across = visible[(geom.box[visible, 0] > 0) & (geom.box[visible, 2] < w_img)]
        rest_width = geom.box[across[0], 2] - geom.box[across[0], 0] if len(across) else np.inf
        pos = np.zeros((N, 3))
        sizes = []
        for k in visible:
            u0, v0, u1, v1 = geom.box[k]
            bottom_pixel = np.array([0.5 * (u0 + u1), v1])
            bottom, depth = ground_point(bottom_pixel)
            if not on_ground:
                depth = rest_depth
                bottom = centre + depth * _rays(bottom_pixel[None], K, R_wc)[0]
            width = (u1 - u0) * depth / K[0, 0]
            height = np.clip((v1 - v0) * depth / K[1, 1] * 0.6, 0.03, 0.4)
            if carried[k] and u0 > 0 and u1 < w_img and u1 - u0 > APPROACH_GROWTH * rest_width:
                depth = rest_depth * rest_width / (u1 - u0)
                pos[k] = centre + depth * _rays(np.array([[0.5 * (u0 + u1), 0.5 * (v0 + v1)]]), K, R_wc)[0]
                continue
            sizes.append([width, width, height])
            pos[k] = bottom + np.array([0.0, 0.5 * width, 0.5 * height])
        size = np.clip(np.median(np.array(sizes), 0), 0.03, 0.5)
        return _fill_missing(pos, geom.visible), size, np.asarray(geom.visible)

    object_pos, object_size, _ = cuboid_from_masks(object_geom, object_depth == "on the ground")
    static_pos, static_size = [], []
    for j in range(num_static):
        pos, size, visible = cuboid_from_masks(_MaskGeometry(targets[:, 2 + j]), True)
        static_pos.append(pos[np.flatnonzero(visible)[0]])
        static_size.append(size)
    if on_static:
        object_pos = _placed_on_static(object_pos, object_size, object_geom, np.asarray(contact, bool), resting,
                                       static_pos[0], static_size[0], centre, K, R_wc)

    toward = _hand_tilt(hand_geom, K) if hand_width and hand_tilt else None
    toward = TYPICAL_HAND_TILT if toward is None else toward
    hand_pos = np.zeros((N, 3))
    hand_axis = np.zeros((N, 3))
    for k in np.flatnonzero(hand_geom.visible):
        pixels = hand_geom.pixels(k)
        tip = pixels[np.argmin(((pixels - object_centroid[k]) ** 2).sum(1))]
        tip_depth = ((object_pos[k] - centre) @ R_wc)[2]
        hand_pos[k] = centre + tip_depth * _rays(tip[None], K, R_wc)[0]
        arm = hand_geom.centroid[k] - tip
        arm = arm / np.linalg.norm(arm) if np.linalg.norm(arm) > 1e-6 else np.array([0.0, 1.0])
        hand_axis[k] = R_wc @ np.array([*(np.sqrt(1.0 - toward**2) * arm), -toward])
    hand_pos = _fill_missing(hand_pos, hand_geom.visible)
    hand_axis = _fill_missing(hand_axis, hand_geom.visible)
    hand_rot = frame_from_axis(hand_axis)

    f = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
    static_size_t = f(np.reshape(static_size, (num_static, 3)))
    static_xy = f(np.reshape(static_pos, (num_static, 3))[:, :2])
    s_pos, s_rot = static_poses(static_xy, torch.zeros(num_static), static_size_t)
    return SceneTrajectories(
        hand_pos=f(hand_pos),
        hand_rot=f(hand_rot),
        object_pos=f(object_pos),
        object_rot=torch.eye(3).expand(N, 3, 3).clone(),
        object_size=f(object_size),
        static_pos=s_pos,
        static_rot=s_rot,
        static_size=static_size_t,
        camera_height=torch.tensor(h0),
        camera_elevation=torch.tensor(e0),
    )


def _placed_on_static(
    object_pos: np.ndarray, object_size: np.ndarray, geom: _MaskGeometry, contact: np.ndarray, resting: np.ndarray,
    static_pos: np.ndarray, static_size: np.ndarray, camera: np.ndarray, K: np.ndarray, R_wc: np.ndarray,
) -> np.ndarray:
    """Object centres (N, 3) that stand on the static box's top in the ``resting`` frames,
    below the mask's bottom edge, and are carried there during the contact (their camera
    depth moving from where the object started to where it rests); the static box
    (``static_pos``, ``static_size``, changed in place) reaches under the object."""
    offset = np.array([0.0, 0.5 * object_size[1], 0.5 * object_size[2]])

    def bottom_ray(k: int) -> np.ndarray:
        u0, _, u1, v1 = geom.box[k]
        return _rays(np.array([[0.5 * (u0 + u1), v1]]), K, R_wc)[0]

    pos = object_pos.copy()
    top = static_size[2]
    for k in np.flatnonzero(resting & geom.visible):
        ray = bottom_ray(k)
        t = (top - camera[2]) / ray[2] if ray[2] < -1e-3 else 1.0
        pos[k] = camera + min(t, 3.0) * ray + offset
    rest = pos[resting & geom.visible].mean(0) if (resting & geom.visible).any() else pos[resting].mean(0)
    pos[resting & ~geom.visible] = rest
    held = np.flatnonzero(contact)
    if len(held) > 1:
        depth = lambda p: float((p - camera) @ R_wc[:, 2])  # noqa: E731
        start, end = depth(pos[held[0]] - offset), depth(rest - offset)
        for k in held[geom.visible[held]]:
            share = (k - held[0]) / (held[-1] + 1 - held[0])
            pos[k] = camera + ((1 - share) * start + share * end) * bottom_ray(k) + offset
    lo = np.minimum(static_pos[:2] - 0.5 * static_size[:2], rest[:2] - 0.5 * object_size[:2])
    hi = np.maximum(static_pos[:2] + 0.5 * static_size[:2], rest[:2] + 0.5 * object_size[:2])
    static_pos[:2], static_size[:2] = 0.5 * (lo + hi), hi - lo
    return pos


class InitialParameters(torch.nn.Module):
    """Free per-frame parameters of stage (a), initialised from a :class:`SceneTrajectories`.

    The object stays upright (it turns about z only): an upright box shows as much of its
    top face as the camera's elevation dictates, which makes the elevation observable.
    A global scale multiplies every position, size and the camera height: scaling the
    whole scene about the camera changes only the hand's apparent width (its size is
    fixed), a direction too flat for per-frame parameters to follow one by one.

    ``known`` lengths (:data:`warpskill.optimizer.known.KNOWN_LENGTHS` -> metres) replace that
    scale: it is whatever makes the first of them come out at its value, and the others
    are put in exactly.
    """

    def __init__(self, guess: SceneTrajectories, known: dict[str, float] | None = None):
        super().__init__()
        self.known = dict(known or {})
        P = torch.nn.Parameter
        self.hand_pos = P(guess.hand_pos.clone())
        self.hand_rot6 = P(rotation_to_6d(guess.hand_rot))
        self.object_pos = P(guess.object_pos.clone())
        self.object_yaw = P(torch.atan2(guess.object_rot[:, 1, 0], guess.object_rot[:, 0, 0]))
        self.object_size_raw = P(positive_inverse(guess.object_size, MIN_OBJECT_SIZE))
        self.static_xy = P(guess.static_pos[:, :2].clone())
        self.static_yaw = P(torch.zeros(guess.static_pos.shape[0]))
        self.static_size_raw = P(positive_inverse(guess.static_size, MIN_STATIC_SIZE))
        self.camera_height_raw = P(positive_inverse(guess.camera_height, 0.05))
        self.camera_elevation = P(guess.camera_elevation.clone())
        self.log_scale = P(torch.zeros(()))

    def scene(self) -> SceneTrajectories:
        """The per-frame scene these parameters describe."""
        object_size = positive(self.object_size_raw, MIN_OBJECT_SIZE)
        static_size = positive(self.static_size_raw, MIN_STATIC_SIZE)
        camera_height = positive(self.camera_height_raw, 0.05)
        scale = self.log_scale.exp()
        for name, value in self.known.items():
            unscaled = measured(name, object_size, static_size, camera_height)
            if unscaled is not None:
                scale = value / unscaled
                break
        object_size, static_size, camera_height = pin_sizes(
            self.known, scale * object_size, scale * static_size, scale * camera_height
        )
        static_pos, static_rot = static_poses(scale * self.static_xy, self.static_yaw, static_size)
        return SceneTrajectories(
            hand_pos=scale * self.hand_pos,
            hand_rot=rotation_from_6d(self.hand_rot6),
            object_pos=scale * self.object_pos,
            object_rot=yaw_rotation(self.object_yaw),
            object_size=object_size,
            static_pos=static_pos,
            static_rot=static_rot,
            static_size=static_size,
            camera_height=camera_height,
            camera_elevation=self.camera_elevation,
        )


def _far_from_contact(contact: torch.Tensor, margin: int) -> torch.Tensor:
    """(N,) 1 in frames more than ``margin`` frames away from any contact frame, else 0.

    Contact signals are off by a frame or two around the onset and release; the resting
    priors trust only the frames that are clearly free.
    """
    near = torch.nn.functional.max_pool1d(contact[None, None], 2 * margin + 1, stride=1, padding=margin)[0, 0]
    return 1.0 - near


def initial_objective(
    scene: SceneTrajectories,
    rendered: torch.Tensor,
    targets: MaskTargets,
    contact: torch.Tensor,
    fps: float,
    weights: LossWeights,
    uncertain: torch.Tensor | None = None,
    supported: torch.Tensor | None = None,
    behind: torch.Tensor | None = None,
) -> dict[str, torch.Tensor]:
    """Stage (a) loss terms: perceptual, contact distance, smoothness and resting priors.

    Args:
        scene: the per-frame scene.
        rendered: (N, 2 + K, h, w) its soft silhouettes at the working resolution, or their
            :class:`~warpskill.optimizer.losses.MaskProfile` against ``targets``.
        targets: the masks at the working resolution.
        contact: (N,) contact signal in {0, 1}.
        fps: frame rate [1/s].
        weights: loss weights.
        uncertain: (N,) 1 in frames whose contact is in doubt (the object may still be held
            after the signal ends): neither the contact nor the resting priors apply there.
        supported: (N,) 1 in frames where the object stands on the first static box (the
            hypothesis "on the static"): its centre is asked to lie over the box's footprint.
        behind: (N,) 1 in frames where the first static box hides the object's lower part
            (:func:`warpskill.optimizer.inputs.cut_by_static`): its centre is asked to lie
            behind the box's back.
    """
    tip_distance = box_signed_distance(scene.hand_pos, scene.object_pos, scene.object_rot, scene.object_size)
    c = contact.to(tip_distance.dtype)
    known_state = 1.0 if uncertain is None else 1.0 - uncertain.to(c)

    def acceleration(x):  # (N, D) -> mean squared second difference [per s^2]
        return ((x[2:] - 2 * x[1:-1] + x[:-2]) * fps**2).square().sum(-1).mean() if len(x) > 2 else x.sum() * 0

    rot6 = rotation_to_6d
    free = _far_from_contact(c, FREE_MARGIN_FRAMES) * known_state
    c = c * known_state
    free_steps = free[1:] * free[:-1]
    moved = ((scene.object_pos[1:] - scene.object_pos[:-1]) * fps).square().sum(-1)
    low = lowest_corner_height(scene.object_pos, scene.object_rot, scene.object_size)
    below = (-low).clamp_min(0.0).square().mean() + (-scene.hand_pos[:, 2]).clamp_min(0.0).square().mean()
    support = support_height(scene.object_pos, scene.static_pos, scene.static_rot, scene.static_size)
    return {
        "perceptual": perceptual_loss(rendered, targets, weights),
        "contact distance": weights.contact_distance
        * (c * (tip_distance + weights.grasp_margin).clamp_min(0.0) ** 2).mean(),
        "smoothness": weights.smoothness
        * (
            acceleration(scene.hand_pos)
            + acceleration(scene.object_pos)
            + 0.01 * (acceleration(rot6(scene.hand_rot)) + acceleration(rot6(scene.object_rot)))
        ),
        # The object does not move while the hand does not touch it, and rests on what is
        # under it (the ground or a static cuboid's top) ...
        "resting": weights.resting * (free_steps * moved).mean()
        + weights.penetration * (free * (low - support).square()).mean(),
        # ... and nothing goes through the ground.
        "penetration": weights.penetration * below,
    } | scene_priors(scene, weights, supported, behind)
