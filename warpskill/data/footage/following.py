"""Object masks for a whole video from an outline on one frame, robust to the hand.

The user outlines the manipulated object and the static objects on one frame (polygons or
rectangles, :func:`warpskill.data.readers.polygons.read_polygons`); :func:`follow_objects`
carries each outline to every frame, forward and backward from that frame. Unlike
:func:`warpskill.data.footage.propagation.propagate_masks`, which moves a mask with the dense flow
inside it and cleans it each frame (so errors accumulate in the shape), each label here is
one *similarity transform* (rotation, scale, shift) of its key-frame outline per frame:

- the motion from one frame to the next is fitted (RANSAC) to sparse corners tracked
  inside the label's visible part (pyramidal Lucas-Kanade, kept only where tracking back
  returns to the start), away from the hand: pixels of the occluder (the hand's masks,
  found independently) never move an object;
- a label with too few tracked corners (hidden behind the hand, out of view, or without
  texture) moves with the background (the camera's motion, fitted the same way to corners
  outside every label and the hand), so a static object follows a moving camera and a
  covered object keeps its place in the scene;
- each frame the label's key-frame appearance is searched for around the predicted place
  (normalised cross-correlation of the outline's inner part, at the predicted scale); a
  confident match elsewhere moves the label there (drift, fast jumps, re-entry);
- the key-frame outline itself is warped, so a part that leaves the view or hides behind
  the hand comes back whole.

Masks are visible masks: the occluder is in front of everything, then the labels in the
order given (object first, then static objects).

Limits: a label moves rigidly (a similarity), so deforming objects are followed only by
their box; an object whose appearance changes (turned over, transparent) is followed by
its corners alone; a grasped object fully hidden in the hand stays with the background.
"""

from __future__ import annotations

import cv2
import numpy as np

from warpskill.data.footage.tracking import (
    LK_WINDOW_PX,
    OBJECT_CORNERS,
    OBJECT_MAX_SCALE_STEP,
    OBJECT_RANSAC_PX,
    carried_corners,
)

FOLLOW_SIDE = 240
"""Objects are followed on frames reduced until their shorter side has this many px (the real
clips' size, for which the px settings here are made), the key outlines then moved at full size."""

EDGE_PX = 2
"""Corners this close [px] to a label's edge or the occluder are not tracked (they mix
the label with what surrounds it)."""

MIN_CORNERS = 6
"""Fewest inlier corners whose motion moves a label; fewer: it moves with the background."""

COVERED = 0.3
"""Share of a label hidden by the hand from which, its own corners lost, it keeps its last
motion (it was moving: it goes on moving behind the hand) rather than the background's."""

COAST_FRAMES = 3
"""A label coasting (hidden or leaving the view) shifts by the mean of its last this many own shifts."""

ALIGN_MARGIN_PX = 4
"""Extra px around a part (beyond its shift) in which its pixels are aligned with the next frame."""

ALIGN_MAX_PX = 3.0
"""Most an alignment may change the corners' shift [px]; more is taken for a failed alignment."""

ALIGN_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01)
"""When the alignment stops: 30 iterations or a step under 0.01 px."""

SIMILARITY_GAIN = 1.2
"""A similarity moves a label only when it fits this many times as many corners as a
plain shift (rotation and scale from a few close corners are mostly noise)."""

IN_VIEW = 0.9
"""A label touching the image border with less than this fraction of its key-frame area
in view is leaving it: without tracked corners it keeps its last own motion."""

TEMPLATE_INSET = 0.15
"""Fraction of the outline's box cut from each side for the appearance template (the
rim of a hurried outline is background)."""

MIN_TEMPLATE_PX = 8
"""Smallest template side [px]; a smaller label is not re-found by appearance."""

SEARCH_MARGIN = 0.5
"""The appearance is searched within this fraction of the label's box size (and at least
:data:`MIN_SEARCH_PX`) around its predicted place."""

LOST_SCORE = 0.5
"""Normalised cross-correlation at the predicted place below which the label counts as lost
there (its corners followed something else): its appearance is then searched for farther."""

LOST_SEARCH_MARGIN = 2.0
"""Search radius around the predicted place of a lost label, in its box sizes."""

MIN_SEARCH_PX = 12
"""Least search radius [px] around the predicted place."""

MATCH_SCORE = 0.9
"""Normalised cross-correlation from which a match elsewhere is trusted."""

MATCH_GAIN = 0.15
"""How much better than at the predicted place a match must score to move the label."""

MIN_VISIBLE = 0.5
"""Fraction of a label's in-view template area that must be free of the occluder to
search for its appearance."""


def follow_objects(
    frames: np.ndarray,
    key_frame: int,
    key_masks: dict[str, np.ndarray],
    *,
    occluder: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Carry the key frame's object masks to every frame: :func:`follow_outlines`, then
    :func:`visible_masks` (same arguments and errors).

    Returns:
        label -> (N, H, W) bool visible masks: each label's outline moved to each frame,
        minus the occluder and the labels before it.
    """
    occluder = None if occluder is None else np.asarray(occluder)
    return visible_masks(follow_outlines(frames, key_frame, key_masks, occluder=occluder), occluder)


def visible_masks(whole: dict[str, np.ndarray], occluder: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """What is seen of whole masks (label -> (N, H, W) bool, front to back) behind the
    occluder ((N, H, W) bool, in front of every label, or None): each pixel to the first
    that covers it."""
    out = {}
    hidden = None if occluder is None else occluder.astype(bool).copy()
    for label, masks in whole.items():
        out[label] = masks.copy() if hidden is None else masks & ~hidden
        hidden = masks.copy() if hidden is None else hidden | masks
    return out


def follow_outlines(
    frames: np.ndarray,
    key_frame: int,
    key_masks: dict[str, np.ndarray],
    *,
    occluder: np.ndarray | None = None,
    carried: dict[str, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """Carry the key frame's object outlines to every frame whole, hidden parts included
    (see the module docstring).

    Args:
        frames: (N, H, W, 3) uint8 RGB video frames.
        key_frame: 0-based index of the outlined frame.
        key_masks: label -> (H, W) bool mask on the key frame, front to back
            (``object``, ``static_0``, ``static_1``, ...).
        occluder: optional (N, H, W) bool, the hand's masks, in front of every label.
        carried: label -> (N,) bool, the frames in which the hand holds that label (the
            contact): there a label with too few corners of its own moves with the hand
            (corners inside the occluder), not with the background.

    Returns:
        label -> (N, H, W) bool whole masks: each label's outline moved to each frame (the
        key mask itself on the key frame), parts behind the hand or other labels included.

    Raises:
        ValueError: frames not (N, H, W, 3) uint8, ``key_frame`` out of range, no key masks,
            a key mask not (H, W) bool or empty, or an occluder not (N, H, W) bool.
    """
    frames, key_frame, labels, key, occluder = _checked(frames, key_frame, key_masks, occluder)
    n, h, w = frames.shape[:3]
    held = np.zeros((len(labels), n), dtype=bool)
    for label, frames_held in (carried or {}).items():
        if label not in labels or np.shape(frames_held) != (n,):
            raise ValueError(f"carried[{label!r}]: expected a label of key_masks and (N,) = ({n},) bool frames")
        held[labels.index(label)] = np.asarray(frames_held, dtype=bool)
    gray = np.stack([cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY) for frame in frames])
    if min(h, w) > FOLLOW_SIDE:  # followed on reduced frames, the outlines moved at full size
        size = (round(w * FOLLOW_SIDE / min(h, w)), round(h * FOLLOW_SIDE / min(h, w)))  # (width, height)
        small = np.stack([_reduced(mask, size, 0.5 if _reduced(mask, size, 0.5).any() else 0.0) for mask in key])
        hidden = np.stack([_reduced(mask, size, 0.0) for mask in occluder])
        gray = np.stack([cv2.resize(image, size, interpolation=cv2.INTER_AREA) for image in gray])
        transforms = _enlarged(_transforms(gray, key_frame, small, hidden, held), (h, w), size)
        transforms[:, key_frame] = np.eye(2, 3)  # the outline itself where it was drawn
    else:
        transforms = _transforms(gray, key_frame, key, occluder, held)
    return {label: np.stack([_warp(key[i], transforms[i, k]) for k in range(n)]) for i, label in enumerate(labels)}


def _reduced(mask: np.ndarray, size: tuple[int, int], share: float) -> np.ndarray:
    """An (H, W) bool mask reduced to ``size`` (width, height) by area: the pixels more than
    ``share`` covered (0: any part; a key outline too thin to cover half a pixel anywhere)."""
    return cv2.resize(mask.astype(np.float32), size, interpolation=cv2.INTER_AREA) > share


def _enlarged(transforms: np.ndarray, image_size: tuple[int, int], size: tuple[int, int]) -> np.ndarray:
    """(..., 2, 3) transforms between reduced frames of ``size`` (width, height) as the same
    motions between the (H, W) frames (pixel centres mapped as ``cv2.resize`` maps them)."""
    (h, w), (width, height) = image_size, size
    sx, sy = width / w, height / h
    reduce = np.array([[sx, 0, 0.5 * sx - 0.5], [0, sy, 0.5 * sy - 0.5], [0, 0, 1]])
    square = np.zeros((*transforms.shape[:-2], 3, 3))
    square[..., :2, :], square[..., 2, 2] = transforms, 1
    return (np.linalg.inv(reduce) @ square @ reduce)[..., :2, :]


def _transforms(gray: np.ndarray, key_frame: int, key: np.ndarray, occluder: np.ndarray, held: np.ndarray) -> np.ndarray:
    """(L, N, 2, 3) each label's similarity from the key frame to every frame (see the module
    docstring), from the (N, H, W) grey frames, the (L, H, W) key masks, the (N, H, W) occluder
    and the (L, N) frames in which each label is held."""
    n = len(gray)
    templates = [_template(gray[key_frame], mask) for mask in key]
    transforms = np.zeros((len(key), n, 2, 3))
    transforms[:, key_frame] = np.eye(2, 3)
    for step in (1, -1):
        recent = [[] for _ in key]  # each label's last own shifts, for coasting
        for k in range(key_frame + step, n if step > 0 else -1, step):
            before = transforms[:, k - step]
            whole = np.stack([_warp(mask, t) for mask, t in zip(key, before)])
            background = _background_motion(gray[k - step], gray[k], whole, occluder[k - step])
            hand = None  # the occluder's own motion, fitted when a held label needs it
            hidden = occluder[k - step].copy()
            for i in range(len(key)):
                visible = whole[i] & ~hidden
                hidden |= whole[i]
                motion = _label_motion(gray[k - step], gray[k], visible, occluder[k - step] | occluder[k])
                if motion is not None:
                    recent[i] = (recent[i] + [motion[:, 2]])[-COAST_FRAMES:]
                elif held[i, k - step] and held[i, k]:  # held: moves with the hand
                    hand = _hand_motion(gray[k - step], gray[k], occluder[k - step]) if hand is None else hand
                    motion = hand if hand is not False else None
                if motion is None and recent[i] and (
                    _leaving(whole[i], key[i]) or _covered(whole[i], occluder[k - step])
                ):  # hidden behind the hand or on its way out of view: keeps going
                    motion = np.hstack([np.eye(2), np.mean(recent[i], axis=0)[:, None]])
                t = _compose(motion if motion is not None else background, before[i])
                if templates[i] is not None:
                    t = _refound(gray[k], t, templates[i], occluder[k])
                transforms[i, k] = t
    return transforms


def _checked(frames, key_frame, key_masks, occluder):
    """The inputs, checked: frames, key frame, labels, (L, H, W) key masks, (N, H, W) occluder."""
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[3] != 3 or frames.dtype != np.uint8:
        raise ValueError(f"frames: expected (N, H, W, 3) uint8, got {frames.dtype} of shape {frames.shape}")
    n, h, w = frames.shape[:3]
    if isinstance(key_frame, bool) or not isinstance(key_frame, (int, np.integer)) or not 0 <= key_frame < n:
        raise ValueError(f"key_frame: expected an integer in 0..{n - 1}, got {key_frame!r}")
    if not key_masks:
        raise ValueError("key_masks: expected at least one label -> (H, W) bool mask")
    labels = list(key_masks)
    key = []
    for label in labels:
        mask = np.asarray(key_masks[label])
        if mask.shape != (h, w) or mask.dtype != bool:
            raise ValueError(f"key_masks[{label!r}]: expected ({h}, {w}) bool, got {mask.dtype} of shape {mask.shape}")
        if not mask.any():
            raise ValueError(f"key_masks[{label!r}]: empty mask on the key frame")
        key.append(mask)
    if occluder is None:
        occluder = np.zeros((n, h, w), dtype=bool)
    occluder = np.asarray(occluder)
    if occluder.shape != (n, h, w) or occluder.dtype != bool:
        raise ValueError(f"occluder: expected ({n}, {h}, {w}) bool, got {occluder.dtype} of shape {occluder.shape}")
    return frames, int(key_frame), labels, np.stack(key), occluder


def _warp(mask: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """(H, W) bool key mask moved by a 2 x 3 transform, clipped to the image."""
    h, w = mask.shape
    moved = cv2.warpAffine(mask.astype(np.uint8) * 255, transform.astype(np.float64), (w, h), flags=cv2.INTER_LINEAR)
    return moved >= 128


def _leaving(whole: np.ndarray, key: np.ndarray) -> bool:
    """Whether a label's moved mask ``whole`` is partly out of view: it touches the image's
    border and is less than :data:`IN_VIEW` of its key-frame area."""
    touches = whole[0].any() or whole[-1].any() or whole[:, 0].any() or whole[:, -1].any()
    return bool(touches and whole.sum() < IN_VIEW * key.sum())


def _covered(whole: np.ndarray, occluder: np.ndarray) -> bool:
    """Whether the occluder hides more than :data:`COVERED` of a whole mask."""
    return bool((whole & occluder).sum() > COVERED * whole.sum())


def _compose(step: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """The 2 x 3 transform ``step`` applied after ``transform``."""
    return step[:, :2] @ transform + np.hstack([np.zeros((2, 2)), step[:, 2:]])


def _tracked(before: np.ndarray, after: np.ndarray, where: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corners inside ``where`` (H, W uint8) of ``before`` and their places in ``after``, those
    that track back (:func:`~warpskill.data.footage.tracking.carried_corners`): two (M, 2) float32 [px]."""
    corners = OBJECT_CORNERS.find(before, where)
    if corners is None or len(corners) < 2 * MIN_CORNERS:  # a small or thin part: a grid of its pixels too
        spacing = OBJECT_CORNERS.spacing_px
        ys, xs = np.nonzero(where[::spacing, ::spacing])
        pick = np.linspace(0, len(xs) - 1, min(len(xs), OBJECT_CORNERS.most)).astype(int)
        grid = np.stack([xs[pick], ys[pick]], axis=1).astype(np.float32)[:, None] * spacing
        corners = grid if corners is None else np.concatenate([corners, grid])
    if len(corners) < MIN_CORNERS:
        return np.zeros((0, 2), np.float32), np.zeros((0, 2), np.float32)
    return carried_corners(before, after, corners)


def _similarity(source: np.ndarray, target: np.ndarray) -> np.ndarray | None:
    """Similarity (2 x 3) fitted with RANSAC to corner pairs; None for too few inliers."""
    if len(source) < MIN_CORNERS:
        return None
    shift = np.median(target - source, axis=0)
    shifted = np.linalg.norm(target - source - shift, axis=1) < OBJECT_RANSAC_PX
    transform, inliers = cv2.estimateAffinePartial2D(source, target, method=cv2.RANSAC,
                                                     ransacReprojThreshold=OBJECT_RANSAC_PX)
    if transform is None or inliers.sum() < SIMILARITY_GAIN * shifted.sum():  # a shift explains it as well
        if shifted.sum() < MIN_CORNERS:
            return None
        shift = (target - source)[shifted].mean(axis=0)
        return np.hstack([np.eye(2), shift[:, None]])
    scale = np.sqrt(abs(np.linalg.det(transform[:, :2])))
    if abs(scale - 1) > OBJECT_MAX_SCALE_STEP:  # rescale about the inliers' centre
        centre = source[inliers[:, 0] == 1].mean(axis=0)
        linear = transform[:, :2] * (np.clip(scale, 1 - OBJECT_MAX_SCALE_STEP, 1 + OBJECT_MAX_SCALE_STEP) / scale)
        moved = transform[:, :2] @ centre + transform[:, 2]
        transform = np.hstack([linear, (moved - linear @ centre)[:, None]])
    return transform


def _inner(mask: np.ndarray, occluder: np.ndarray) -> np.ndarray:
    """uint8 mask of ``mask`` at least :data:`EDGE_PX` from its edge and from ``occluder``,
    and half a tracking window from the image border."""
    size = 2 * EDGE_PX + 1
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    inner = cv2.erode(mask.astype(np.uint8), kernel, borderType=cv2.BORDER_REPLICATE)
    rim = LK_WINDOW_PX // 2  # a window reaching past the image border holds a corner back
    inner[:rim], inner[-rim:], inner[:, :rim], inner[:, -rim:] = 0, 0, 0, 0
    return inner & ~cv2.dilate(occluder.astype(np.uint8), kernel) & 1


def _label_motion(before, after, visible, occluder) -> np.ndarray | None:
    """The similarity moving a label's ``visible`` part from ``before`` to ``after`` (grey
    frames), from corners away from the occluder, a plain shift then aligned on the part's
    own pixels (:func:`_aligned`); None when too few are tracked."""
    where = _inner(visible, occluder)
    if where.sum() < MIN_CORNERS:
        return None
    motion = _similarity(*_tracked(before, after, where * 255))
    if motion is None or not np.allclose(motion[:, :2], np.eye(2)):
        return motion
    return _aligned(before, after, where, motion)


def _aligned(before, after, where, motion) -> np.ndarray:
    """A shift (2 x 3) refined by aligning the pixels of ``where`` in ``before`` with
    ``after`` (OpenCV's ECC, translation): corners' windows reach past a small part's edge
    into the background, which holds their flow back; ECC sees the part's pixels alone.
    ``motion`` itself where the alignment fails or moves more than :data:`ALIGN_MAX_PX`."""
    ys, xs = np.nonzero(where)
    margin = int(np.ceil(np.abs(motion[:, 2]).max())) + ALIGN_MARGIN_PX
    h, w = where.shape
    y0, y1 = max(ys.min() - margin, 0), min(ys.max() + 1 + margin, h)
    x0, x1 = max(xs.min() - margin, 0), min(xs.max() + 1 + margin, w)
    warp = motion.astype(np.float32).copy()
    try:
        _, warp = cv2.findTransformECC(before[y0:y1, x0:x1], after[y0:y1, x0:x1], warp, cv2.MOTION_TRANSLATION,
                                       ALIGN_CRITERIA, where[y0:y1, x0:x1].astype(np.uint8), 1)
    except cv2.error:  # too little texture: the corners' shift stands
        return motion
    if np.abs(warp[:, 2] - motion[:, 2]).max() > ALIGN_MAX_PX:
        return motion
    return np.hstack([np.eye(2), warp[:, 2:].astype(float)])


def _background_motion(before, after, whole, occluder) -> np.ndarray:
    """The camera's motion: the similarity fitted to corners outside every label and the
    occluder; identity when too few are tracked."""
    motion = _label_motion(before, after, ~(whole.any(axis=0) | occluder), occluder)
    return np.eye(2, 3) if motion is None else motion


def _hand_motion(before, after, occluder) -> np.ndarray | bool:
    """The hand's motion: the similarity fitted to corners inside the occluder; False when
    too few are tracked."""
    motion = _label_motion(before, after, occluder, np.zeros_like(occluder))
    return False if motion is None else motion


def _template(gray: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The key-frame appearance of a label: the inner part of its box (grey, float32) and
    that part's centre in key-frame px; None when too small."""
    ys, xs = np.nonzero(mask)
    x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    dx, dy = int(TEMPLATE_INSET * (x1 - x0)), int(TEMPLATE_INSET * (y1 - y0))
    x0, x1, y0, y1 = x0 + dx, x1 - dx, y0 + dy, y1 - dy
    if min(x1 - x0, y1 - y0) < MIN_TEMPLATE_PX:
        return None
    return gray[y0:y1, x0:x1].astype(np.float32), np.array([(x0 + x1) / 2, (y0 + y1) / 2])


def _match(window: np.ndarray, patch: np.ndarray) -> float:
    """Normalised cross-correlation of a same-sized grey window and patch (-1 where flat)."""
    score = cv2.matchTemplate(window.astype(np.float32), patch, cv2.TM_CCOEFF_NORMED)[0, 0]
    return float(np.nan_to_num(score, nan=-1.0))


def _refound(gray: np.ndarray, transform: np.ndarray, template, occluder: np.ndarray) -> np.ndarray:
    """``transform`` shifted to where the label's key-frame appearance matches best near
    its predicted place in ``gray``, if that match is confident (:data:`MATCH_SCORE`) and
    clearly better than at the predicted place (:data:`MATCH_GAIN`)."""
    patch, centre = template
    scale = np.sqrt(abs(np.linalg.det(transform[:, :2])))
    th, tw = max(int(round(patch.shape[0] * scale)), 1), max(int(round(patch.shape[1] * scale)), 1)
    h, w = gray.shape
    if min(th, tw) < MIN_TEMPLATE_PX or th >= h or tw >= w:
        return transform
    cx, cy = transform[:, :2] @ centre + transform[:, 2]
    px, py = int(round(cx - tw / 2)), int(round(cy - th / 2))  # predicted top-left corner
    inside = 0 <= px and 0 <= py and px + tw <= w and py + th <= h
    if inside and occluder[py : py + th, px : px + tw].mean() > 1 - MIN_VISIBLE:
        return transform
    patch = cv2.resize(patch, (tw, th), interpolation=cv2.INTER_AREA)
    here = _match(gray[py : py + th, px : px + tw], patch) if inside else -1.0
    margin = SEARCH_MARGIN if here >= LOST_SCORE else LOST_SEARCH_MARGIN  # lost: looks farther
    rx, ry = max(int(margin * tw), MIN_SEARCH_PX), max(int(margin * th), MIN_SEARCH_PX)
    # the search window, at least one template large inside the image (a label out of view
    # is searched for along the border it left by)
    x0, y0 = int(np.clip(px - rx, 0, w - tw)), int(np.clip(py - ry, 0, h - th))
    x1, y1 = int(np.clip(px + tw + rx, x0 + tw, w)), int(np.clip(py + th + ry, y0 + th, h))
    scores = cv2.matchTemplate(gray[y0:y1, x0:x1].astype(np.float32), patch, cv2.TM_CCOEFF_NORMED)
    scores = np.nan_to_num(scores, nan=-1.0)
    best = np.unravel_index(np.argmax(scores), scores.shape)
    if not inside and occluder[best[0] + y0 : best[0] + y0 + th, best[1] + x0 : best[1] + x0 + tw].mean() > 1 - MIN_VISIBLE:
        return transform
    if scores[best] < MATCH_SCORE or scores[best] < here + MATCH_GAIN:
        return transform
    shifted = transform.copy()
    shifted[:, 2] += (best[1] + x0 - px, best[0] + y0 - py)
    return shifted
