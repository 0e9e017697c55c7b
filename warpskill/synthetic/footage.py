"""A synthetic demonstration as a phone clip: textured frames and the outline a user draws.

Each region of the true masks (the table, the static objects, the manipulated object and
the hand) is painted with a texture that moves with the region's projected centre over a
textured table, so optical flow and corner tracking can follow it as on real footage; the
outline of one frame is the true masks' outer contours there (the polygon file of
``docs/formats.md``). Used by ``warpskill bench footage-speed`` to time ``warpskill run``
on a clip whose verdict is known.
"""

from __future__ import annotations

import cv2
import numpy as np

from warpskill.contract.demonstration import Demonstration

__all__ = ["clip_outline", "textured_frames"]

TEXTURES = {"table": ((110, 120, 135), 40, 2.0), "static": ((70, 150, 80), 40, 1.5),
            "object": ((200, 110, 50), 45, 1.5), "hand": ((225, 180, 150), 40, 1.5)}
"""Region -> (mean RGB, spread, blur [px]) of its texture."""


def textured_frames(demo: Demonstration, seed: int = 0) -> np.ndarray:
    """The frames of a synthetic demonstration with ground truth (``demo.truth``).

    Returns:
        (N, H, W, 3) uint8 RGB: the static objects, the object and the hand (front to back)
        over the table, each textured, the object's and hand's textures moving with them.
    """
    rng = np.random.default_rng(seed)
    n, h, w = demo.hand_mask.shape
    size = 2 * max(h, w)
    textures = {name: _texture(rng, size, *look) for name, look in TEXTURES.items()}
    centres = {name: _project(demo.truth[f"{name}_pos"], demo.truth) for name in ("object", "hand")}
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    frames = np.empty((n, h, w, 3), dtype=np.uint8)
    for k in range(n):
        frame = textures["table"][:h, :w].copy()
        for mask in demo.static_mask[:, k]:
            frame[mask] = textures["static"][:h, :w][mask]
        for name, mask in (("object", demo.object_mask[k]), ("hand", demo.hand_mask[k])):
            u, v = centres[name][k]
            moved = cv2.remap(textures[name], xs - np.float32(u - size / 2), ys - np.float32(v - size / 2),
                              cv2.INTER_LINEAR)
            frame[mask] = moved[mask]
        frames[k] = np.clip(frame, 0, 255)
    return frames


def clip_outline(demo: Demonstration, frame: int) -> dict:
    """The polygon file (``docs/formats.md``) a user draws on ``frame``: the hand, the object
    and each static object's true outer contour [px]."""
    return {"frame": int(frame), "hand": _polygon(demo.hand_mask[frame]), "object": _polygon(demo.object_mask[frame]),
            "static": [_polygon(mask[frame]) for mask in demo.static_mask]}


def _texture(rng: np.random.Generator, size: int, base, spread: float, blur: float) -> np.ndarray:
    """(size, size, 3) float32: blurred grey and colour noise about ``base``."""
    lum = cv2.GaussianBlur(rng.normal(0, 1, (size, size)), (0, 0), blur)
    col = cv2.GaussianBlur(rng.normal(0, 1, (size, size, 3)), (0, 0), blur * 2)
    noise = lum[..., None] / lum.std() + 0.35 * col / col.std()
    return np.clip(np.asarray(base) + spread * noise, 0, 255).astype(np.float32)


def _project(points: np.ndarray, truth: dict) -> np.ndarray:
    """(N, 3) world points [m] to (N, 2) pixels, by the camera of docs/formats.md."""
    e, height = float(truth["camera_elevation"]), float(truth["camera_height"])
    rotation = np.array([[1, 0, 0], [0, -np.sin(e), -np.cos(e)], [0, np.cos(e), -np.sin(e)]]).T  # columns: camera axes
    uv = ((points - [0, 0, height]) @ rotation) @ np.asarray(truth["camera_K"]).T
    return uv[:, :2] / uv[:, 2:3]


def _polygon(mask: np.ndarray) -> list[list[float]]:
    """The largest outer contour of a (H, W) bool mask, as [x, y] pixel centres."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    return [[float(x) + 0.5, float(y) + 0.5] for x, y in max(contours, key=cv2.contourArea)[:, 0]]
