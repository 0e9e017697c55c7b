"""Exact NumPy ray casting of the scene: hard visible masks, nearest hit wins.

An independent reference for ``warpskill.engine.rendering`` (true cylinder for the hand, exact boxes,
one ray per pixel centre (u, v) = (j + 0.5, i + 0.5)), also used to render synthetic
demonstrations. The hand is clipped to the same part of its axis as in the rasterizer
(:func:`warpskill.engine.primitives.hand_axis_extent`), which is part of the scene's definition.
"""

from __future__ import annotations

import numpy as np
import torch

from warpskill.contract.camera import Intrinsics
from warpskill.engine.primitives import HAND_RADIUS, hand_axis_extent
from warpskill.engine.projection import camera_rotation


def raycast_masks(
    hand_pos: np.ndarray,
    hand_rot: np.ndarray,
    cuboid_pos: np.ndarray,
    cuboid_rot: np.ndarray,
    cuboid_size: np.ndarray,
    camera_height: float,
    camera_elevation: float,
    intrinsics: Intrinsics,
) -> np.ndarray:
    """Visible masks of the hand and the cuboids by exact ray casting.

    Args:
        hand_pos: (F, 3) hand tip positions [m].
        hand_rot: (F, 3, 3) hand rotations.
        cuboid_pos: (F, C, 3) cuboid centres [m].
        cuboid_rot: (F, C, 3, 3) cuboid rotations.
        cuboid_size: (C, 3) or (F, C, 3) cuboid edge lengths [m].
        camera_height: camera height [m].
        camera_elevation: camera elevation [rad].
        intrinsics: camera intrinsics; ``intrinsics.image_size`` is (H, W).

    Returns:
        (F, 1 + C, H, W) bool: pixel (i, j) of channel k is set where primitive k is the
        first surface its ray meets (channel 0 the hand, then the cuboids).
    """
    hand_pos, hand_rot = np.asarray(hand_pos, float), np.asarray(hand_rot, float)
    cuboid_pos, cuboid_rot = np.asarray(cuboid_pos, float), np.asarray(cuboid_rot, float)
    F, C = cuboid_pos.shape[:2]
    cuboid_size = np.broadcast_to(np.asarray(cuboid_size, float), (F, C, 3))
    height, elevation = float(camera_height), float(camera_elevation)
    camera = torch.tensor(height), torch.tensor(elevation)
    t0, t1, visible = (x.numpy() for x in hand_axis_extent(torch.tensor(hand_pos), torch.tensor(hand_rot), *camera))

    H, W = intrinsics.image_size
    K = intrinsics.K
    v, u = np.mgrid[0:H, 0:W] + 0.5
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1).reshape(-1, 3)
    directions = rays @ camera_rotation(torch.tensor(elevation)).numpy().T  # world; camera depth grows 1 per unit t
    origin = np.array([0.0, 0.0, height])

    masks = np.zeros((F, 1 + C, H * W), dtype=bool)
    for f in range(F):
        depth = np.full((1 + C, H * W), np.inf)
        if visible[f]:
            depth[0] = _cylinder_entry(origin, directions, hand_pos[f], hand_rot[f], t0[f], t1[f])
        for k in range(C):
            depth[1 + k] = _box_entry(origin, directions, cuboid_pos[f, k], cuboid_rot[f, k], cuboid_size[f, k])
        nearest = np.argmin(depth, axis=0)
        hit = np.isfinite(depth.min(axis=0))
        masks[f] = hit & (nearest == np.arange(1 + C)[:, None])
    return masks.reshape(F, 1 + C, H, W)


def _slab(o: float, d: np.ndarray, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Parameter interval [enter, leave] of the rays o + t d (N,) inside lo <= x <= hi."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (lo - o) / d, (hi - o) / d
    parallel, inside = d == 0.0, lo <= o <= hi
    enter = np.where(parallel, -np.inf if inside else np.inf, np.minimum(a, b))
    leave = np.where(parallel, np.inf if inside else -np.inf, np.maximum(a, b))
    return enter, leave


def _entry(enter: np.ndarray, leave: np.ndarray) -> np.ndarray:
    """Entry depth of each ray (inf where it misses; 0 where it starts inside)."""
    hit = (enter <= leave) & (leave > 0.0)
    return np.where(hit, np.maximum(enter, 0.0), np.inf)


def _box_entry(origin, directions, pos, rot, size) -> np.ndarray:
    """Entry depth [m] of the rays (N, 3) into a box (centre, rotation, edge lengths)."""
    o = (origin - pos) @ rot
    d = directions @ rot
    slabs = [_slab(o[i], d[:, i], -size[i] / 2, size[i] / 2) for i in range(3)]
    return _entry(np.max([s[0] for s in slabs], axis=0), np.min([s[1] for s in slabs], axis=0))


def _cylinder_entry(origin, directions, pos, rot, t0, t1) -> np.ndarray:
    """Entry depth [m] of the rays (N, 3) into the hand cylinder, axis part [t0, t1] [m]."""
    o = (origin - pos) @ rot
    d = directions @ rot
    a = d[:, 0] ** 2 + d[:, 1] ** 2  # |o + t d|^2 = r^2 in the local xy plane: a t^2 + b t + c = 0
    b = 2.0 * (o[0] * d[:, 0] + o[1] * d[:, 1])
    c = o[0] ** 2 + o[1] ** 2 - HAND_RADIUS**2
    disc = b**2 - 4.0 * a * c
    parallel = a < 1e-12  # along the axis: inside the tube for all t, or never
    root = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        near = np.where(parallel, -np.inf, (-b - root) / (2.0 * a))
        far = np.where(parallel, np.inf, (-b + root) / (2.0 * a))
    miss = np.where(parallel, c > 0.0, disc < 0.0)
    z_enter, z_leave = _slab(o[2], d[:, 2], t0, t1)
    return _entry(np.where(miss, np.inf, np.maximum(near, z_enter)), np.where(miss, -np.inf, np.minimum(far, z_leave)))
