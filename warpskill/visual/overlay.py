"""The overlay: the reconstruction ray cast into the camera over the demonstration's masks, per frame."""

from __future__ import annotations

import math

import cv2
import numpy as np

from warpskill.contract.camera import Intrinsics
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.engine.primitives import scene_cuboids
from warpskill.engine.raycast import raycast_masks
from warpskill.geometry import is_held
from warpskill.media import HAND_COLOR, OBJECT_COLOR, STATIC_COLOR

FILL_ALPHA = 0.5


MASK_GREYS = {"background": 25, "static": 95, "hand": 165, "object": 235}


MIN_OVERLAY_WIDTH = 320


RENDER_BUDGET = 6_000_000


def overlay_frames(
    recon: Reconstruction,
    demo: Demonstration | None = None,
    *,
    background: np.ndarray | None = None,
    render_scale: float | None = None,
) -> np.ndarray:
    """The overlay video of :func:`save_pictures` as an array.

    Args:
        recon, demo, background, render_scale: as in :func:`save_pictures`.

    Returns:
        (N, s H, s W, 3) uint8 RGB frames, s the smallest whole factor with
        s W >= :data:`MIN_OVERLAY_WIDTH` (1 for ordinary videos); output pixel
        (s i + a, s j + b) shows image pixel (i, j).
    """
    check_picture_inputs(recon, demo, background)
    H, W = (int(x) for x in recon.image_size)
    labels = render_labels(recon, render_scale=render_scale)
    if background is not None:
        base = np.asarray(background, dtype=np.uint8)
    elif demo is not None:
        base = _mask_images(demo)
    else:
        base = np.full((recon.num_frames, H, W, 3), MASK_GREYS["background"], np.uint8)
    s = max(1, math.ceil(MIN_OVERLAY_WIDTH / W))
    if s > 1:
        base = base.repeat(s, axis=1).repeat(s, axis=2)
        labels = labels.repeat(s, axis=1).repeat(s, axis=2)
    frames = _paint(base, labels)
    if demo is not None and background is not None:
        _outline_masks(frames, demo, s)
    contact = None if demo is None else demo.contact
    with_masks = demo is not None and background is None
    for k, frame in enumerate(frames):
        _annotate(frame, recon, k, None if contact is None else bool(contact[k]), with_masks=with_masks)
    return frames


def render_labels(recon: Reconstruction, *, render_scale: float | None = None) -> np.ndarray:
    """Which primitive each pixel sees, ray cast from the reconstruction's camera.

    Args:
        recon: the reconstruction.
        render_scale: ray cast at this fraction of ``recon.image_size`` and enlarge the
            result (nearest pixel); None: 1, or less to stay within :data:`RENDER_BUDGET`.

    Returns:
        (N, H, W) int8: -1 nothing, 0 the hand, 1 the object, 2 + k static object k.
    """
    H, W = (int(x) for x in recon.image_size)
    N = recon.num_frames
    if render_scale is None:
        render_scale = min(1.0, math.sqrt(RENDER_BUDGET / (N * H * W)))
    check_render_scale(render_scale)
    intrinsics = Intrinsics(recon.camera_K, (H, W)).scaled(render_scale)
    cuboid_pos, cuboid_rot, cuboid_size = scene_cuboids(recon)
    masks = raycast_masks(
        recon.hand_pos,
        recon.hand_rot,
        cuboid_pos,
        cuboid_rot,
        cuboid_size,
        float(recon.camera_height),
        float(recon.camera_elevation),
        intrinsics,
    )  # (N, 2 + K, h, w), at most one channel set per pixel
    labels = np.where(masks.any(axis=1), masks.argmax(axis=1), -1).astype(np.int8)
    if intrinsics.image_size != (H, W):
        labels = np.stack([cv2.resize(frame, (W, H), interpolation=cv2.INTER_NEAREST) for frame in labels])
    return labels


def _mask_images(demo: Demonstration) -> np.ndarray:
    """(N, H, W, 3) uint8: the demonstration's masks as grey silhouettes (:data:`MASK_GREYS`)."""
    grey = np.full(demo.hand_mask.shape, MASK_GREYS["background"], np.uint8)
    grey[demo.static_mask.any(axis=0)] = MASK_GREYS["static"]
    grey[demo.hand_mask] = MASK_GREYS["hand"]
    grey[demo.object_mask] = MASK_GREYS["object"]
    return np.repeat(grey[..., None], 3, axis=-1)


def _label_colors(num_labels: int) -> np.ndarray:
    """(num_labels, 3) float RGB of labels 0 (hand), 1 (object), 2.. (static objects)."""
    colors = [HAND_COLOR, OBJECT_COLOR] + [STATIC_COLOR] * (num_labels - 2)
    return np.array(colors[:num_labels], dtype=np.float32)


def _paint(base: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Blend label colours over ``base`` (N, H, W, 3): translucent fill, opaque 1-px outline."""
    colors = _label_colors(max(int(labels.max()) + 1, 2))
    hit = labels >= 0
    edge = np.zeros_like(hit)
    for axis in (1, 2):  # a pixel whose label differs from a 4-neighbour's, on the labelled side
        diff = np.diff(labels, axis=axis) != 0
        before, after = [slice(None)] * 3, [slice(None)] * 3
        before[axis], after[axis] = slice(None, -1), slice(1, None)
        edge[tuple(before)] |= diff
        edge[tuple(after)] |= diff
    edge &= hit
    alpha = np.where(edge[hit], 1.0, FILL_ALPHA).astype(np.float32)[:, None]
    out = base.copy()
    out[hit] = np.round(base[hit] * (1.0 - alpha) + colors[labels[hit]] * alpha).astype(np.uint8)
    return out


def _outline_masks(frames: np.ndarray, demo: Demonstration, s: int) -> None:
    """Outline the demonstration's masks on the frames (enlarged ``s`` times) in place, in each
    role's colour: on real frames, what the reconstruction was fitted to."""
    roles = [(STATIC_COLOR, mask) for mask in demo.static_mask]
    roles += [(OBJECT_COLOR, demo.object_mask), (HAND_COLOR, demo.hand_mask)]
    for color, masks in roles:
        for frame, mask in zip(frames, masks):
            if mask.any():
                big = mask.astype(np.uint8).repeat(s, axis=0).repeat(s, axis=1)
                contours, _ = cv2.findContours(big, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
                cv2.drawContours(frame, contours, -1, color, 1, cv2.LINE_AA)


def _annotate(frame: np.ndarray, recon: Reconstruction, k: int, contact: bool | None, *, with_masks: bool) -> None:
    """Write frame index, time, contact and grasp state (top left) and a colour key (bottom left)."""
    H, W = frame.shape[:2]
    scale = float(np.clip(W / 900.0, 0.35, 0.7))
    thickness = 1
    font = cv2.FONT_HERSHEY_SIMPLEX
    (_, text_h), baseline = cv2.getTextSize("Ag", font, scale, thickness)
    step = text_h + baseline + 3
    held = float(recon.grasped[k])
    lines = [
        (f"frame {k}/{recon.num_frames - 1}  t {recon.t[k]:.2f} s", (255, 255, 255)),
        (f"g {recon.grasp[k]:+.3f}  grasped {held:.2f}", (255, 190, 120) if is_held(held) else (255, 255, 255)),
    ]
    if contact is not None:
        lines.insert(1, ("contact: yes" if contact else "contact: no", (255, 230, 60) if contact else (200, 200, 200)))
    width = max(cv2.getTextSize(text, font, scale, thickness)[0][0] for text, _ in lines)
    _shade(frame, 0, 0, width + 8, step * len(lines) + 4)
    for n, (text, color) in enumerate(lines):
        cv2.putText(frame, text, (4, 2 + step * (n + 1) - baseline), font, scale, color, thickness, cv2.LINE_AA)

    key = [("hand", HAND_COLOR), ("object", OBJECT_COLOR)]
    if recon.num_static:
        key.append(("static", STATIC_COLOR))
    if with_masks:
        key.append(("masks", (MASK_GREYS["object"],) * 3))
    box = text_h
    x, y = 4, H - 4
    total = sum(box + 3 + cv2.getTextSize(name, font, scale, thickness)[0][0] + 8 for name, _ in key)
    _shade(frame, 0, H - box - 8, total + 4, H)
    for name, color in key:
        cv2.rectangle(frame, (x, y - box), (x + box, y), color, -1)
        x += box + 3
        cv2.putText(frame, name, (x, y), font, scale, (255, 255, 255), thickness, cv2.LINE_AA)
        x += cv2.getTextSize(name, font, scale, thickness)[0][0] + 8


def _shade(frame: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> None:
    """Darken the rectangle [x0, x1) x [y0, y1) of ``frame`` in place, so text stays legible."""
    y0, x0 = max(y0, 0), max(x0, 0)
    region = frame[y0:y1, x0:x1]
    region[...] = (region.astype(np.uint16) * 2 // 5).astype(np.uint8)


def check_picture_inputs(recon: Reconstruction, demo: Demonstration | None, background: np.ndarray | None) -> None:
    """Raise ValueError unless ``demo`` and ``background`` match ``recon``'s frames and image."""
    N = recon.num_frames
    size = tuple(int(x) for x in recon.image_size)
    if demo is not None:
        if demo.num_frames != N:
            raise ValueError(f"demonstration has {demo.num_frames} frames, the reconstruction {N}")
        if tuple(demo.image_size) != size:
            raise ValueError(f"demonstration images are {demo.image_size} (H, W), the reconstruction's {size}")
        if not np.allclose(demo.intrinsics.K, recon.camera_K, rtol=1e-6, atol=1e-6):
            raise ValueError(
                f"demonstration camera_K {demo.intrinsics.K.tolist()} differs from the reconstruction's "
                f"{recon.camera_K.tolist()}"
            )
    if background is not None:
        background = np.asarray(background)
        if background.shape != (N, *size, 3) or background.dtype != np.uint8:
            raise ValueError(
                f"background: expected (N, H, W, 3) = {(N, *size, 3)} uint8 RGB frames, "
                f"got {background.shape} {background.dtype}"
            )


def check_render_scale(render_scale: float | None) -> None:
    """Raise ValueError unless ``render_scale`` is None or a fraction in (0, 1]."""
    if render_scale is not None and not 0.0 < render_scale <= 1.0:
        raise ValueError(f"render_scale: expected a fraction in (0, 1], got {render_scale}")
