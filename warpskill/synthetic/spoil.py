"""The errors real inputs have, put into exact masks: jittered boundaries, specks, dropped frames, boxes,
off-by-one contact, and the real annotation files' situations (files that stop early, objects
entering the view, static boxes cut by the frame, hands boxed in part of the frames)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2

import numpy as np

from warpskill.data.boxes.something_else import SomethingElseVideo, box_masks
from warpskill.geometry import is_held
from warpskill.synthetic.scripts import Script


@dataclass(frozen=True)
class Noise:
    """Mask and contact errors of a synthetic demonstration.

    Attributes:
        jitter: largest boundary erosion/dilation radius [px], drawn per frame and mask.
        blob_rate: probability that a frame's mask gains a spurious blob.
        missing_rate: probability that a frame's object mask is lost.
        contact_shift: largest shift [frames] of the contact onset and release.
        contact_flips: number of isolated frames whose contact flag is flipped.
    """

    jitter: int = 0
    blob_rate: float = 0.0
    missing_rate: float = 0.0
    contact_shift: int = 0
    contact_flips: int = 0


NOISE_LEVELS = {
    "none": Noise(),
    "low": Noise(jitter=1, blob_rate=0.03, missing_rate=0.02, contact_shift=1),
    "moderate": Noise(jitter=2, blob_rate=0.08, missing_rate=0.05, contact_shift=1, contact_flips=1),
    "high": Noise(jitter=3, blob_rate=0.15, missing_rate=0.10, contact_shift=2, contact_flips=2),
}


def noisy_channels(masks: np.ndarray, noise: Noise, rng: np.random.Generator):
    """Apply mask noise per channel: (hand (N,H,W), object (N,H,W), statics (K,N,H,W))."""
    hand = _noisy_masks(masks[:, 0], noise, rng, drop=False)
    obj = _noisy_masks(masks[:, 1], noise, rng, drop=True)
    statics = [_noisy_masks(masks[:, j], noise, rng, drop=False) for j in range(2, masks.shape[1])]
    return hand, obj, (np.stack(statics) if statics else None)


def visible_boxes(masks: np.ndarray, noise: Noise, rng: np.random.Generator) -> np.ndarray:
    """Jittered boxes (C, N, 4) (x1, y1, x2, y2) [px] of each channel's visible silhouette in
    masks (N, C, H, W); NaN where a channel is not seen."""
    N, C, H, W = masks.shape
    boxes = np.full((C, N, 4), np.nan)
    for c in range(C):
        for k in range(N):
            rows, cols = np.nonzero(masks[k, c])
            if len(rows) == 0:
                continue
            box = np.array([cols.min(), rows.min(), cols.max() + 1.0, rows.max() + 1.0])
            if noise.jitter:
                box = box + rng.integers(-noise.jitter, noise.jitter + 1, size=4)
            x1, y1, x2, y2 = np.clip(box, 0, [W, H, W, H])
            if x2 - x1 >= 1 and y2 - y1 >= 1:
                boxes[c, k] = x1, y1, x2, y2
    return boxes


def box_channels(masks: np.ndarray, noise: Noise, rng: np.random.Generator):
    """Ellipses inscribed in jittered boxes of each channel's visible silhouette, as box annotations give them."""
    channels = [box_masks(boxes, masks.shape[-2:]) for boxes in visible_boxes(masks, noise, rng)]
    statics = channels[2:]
    return channels[0], channels[1], (np.stack(statics) if statics else None)


def phase_contact(script: Script, truth: dict[str, np.ndarray], masks: np.ndarray) -> np.ndarray:
    """An annotator's action phase: from the grasp onset to the release, or to ``script.phase_end``
    (clipped to the object's last visible frame), as a per-frame contact signal."""
    grasped = is_held(truth["grasped"])
    contact = grasped.copy()
    on = np.flatnonzero(grasped)
    if script.phase_end is not None and len(on):
        seen = np.flatnonzero(masks[:, 1].reshape(len(masks), -1).any(1))
        last = min(int(round(script.phase_end * float(truth["fps"]))), int(seen[-1]) if len(seen) else len(contact))
        contact[:] = False
        contact[on[0] : max(last, on[0]) + 1] = True
    return contact


def _noisy_masks(masks: np.ndarray, noise: Noise, rng: np.random.Generator, *, drop: bool) -> np.ndarray:
    """Masks (N, H, W) with jittered boundaries, spurious blobs and (if ``drop``) lost frames."""
    out = masks.astype(np.uint8)
    H, W = out.shape[1:]
    for k in range(len(out)):
        if noise.jitter:
            r = int(rng.integers(-noise.jitter, noise.jitter + 1))
            if r:
                kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * abs(r) + 1, 2 * abs(r) + 1))
                out[k] = (cv2.dilate if r > 0 else cv2.erode)(out[k], kernel)
        if rng.random() < noise.blob_rate:
            centre = (int(rng.integers(0, W)), int(rng.integers(0, H)))
            axes = (int(rng.integers(2, 8)), int(rng.integers(2, 8)))
            cv2.ellipse(out[k], centre, axes, float(rng.uniform(0, 180)), 0, 360, 1, -1)
        if drop and rng.random() < noise.missing_rate:
            out[k] = 0
    if not out.any():  # never lose every frame of a mask
        out = masks.astype(np.uint8)
    return out.astype(bool)


def noisy_contact(contact: np.ndarray, noise: Noise, rng: np.random.Generator) -> np.ndarray:
    """A contact signal whose onset and release move by up to ``contact_shift`` frames, with flips."""
    out = contact.copy()
    on = np.flatnonzero(contact)
    if noise.contact_shift and len(on):
        first = int(np.clip(on[0] + rng.integers(-noise.contact_shift, noise.contact_shift + 1), 0, len(out) - 1))
        last = int(np.clip(on[-1] + rng.integers(-noise.contact_shift, noise.contact_shift + 1), first, len(out) - 1))
        out[:] = False
        out[first : last + 1] = True
    for k in rng.choice(len(out), size=noise.contact_flips, replace=False):
        out[k] = ~out[k]
    if not out.any():
        out = contact.copy()
    return out


# --------------------------------------------------------------------------- real videos' annotation situations
#
# Spoilers of a box demonstration's annotations: each takes the boxes (C, N, 4) [px] of
# hand, object and static objects (NaN: no box) and the action phase as a per-frame
# contact signal (N,), and returns both changed. The result goes through the real reader
# (:func:`as_annotations`), so frames without boxes reach the optimiser as a real file's do.


def stops_early(boxes: np.ndarray, contact: np.ndarray, rng: np.random.Generator, image_size):
    """The annotation file stops as the leave phase begins: the last 9-21 frames have no box at
    all, and the action phase ends right before them (for a pick-up: after the hand closed on
    the object and the boxes rose)."""
    boxes, contact = boxes.copy(), contact.copy()
    on = np.flatnonzero(contact)
    cut = max(len(contact) - int(rng.integers(9, 22)), int(on[0]) + 2 if len(on) else 1)
    boxes[:, cut:] = np.nan
    if len(on):
        contact[on[0] : cut] = True
    contact[cut:] = False
    return boxes, contact


def enters_view(boxes: np.ndarray, contact: np.ndarray, rng: np.random.Generator, image_size):
    """The object comes in from outside the view: no object box before about the action phase's
    start (-2 to +3 frames around it; about the first 20 frames of a 4 s video)."""
    boxes = boxes.copy()
    on = np.flatnonzero(contact)
    start = int(on[0]) if len(on) else len(contact) // 3
    boxes[1, : max(1, start + int(rng.integers(-2, 4)))] = np.nan
    return boxes, contact


def static_cut_by_frame(boxes: np.ndarray, contact: np.ndarray, rng: np.random.Generator, image_size):
    """A large static object cut by the frame: the static box reaches the image border on the
    side away from the object (and, one time in two, the bottom border), as an annotator boxes
    a shelf or a table top of which only the near part takes the object.

    Never the bottom border where the object ends in front of the static (its last box's
    bottom below the static's): a static object reaching past the view's bottom leaves no
    ground in front of it where the object could be seen standing."""
    boxes = boxes.copy()
    if len(boxes) < 3:
        return boxes, contact
    H, W = image_size
    static, obj = boxes[2], boxes[1]
    seen = np.flatnonzero(~np.isnan(obj[:, 0]))
    object_x = (obj[seen[-1], 0] + obj[seen[-1], 2]) / 2 if len(seen) else W / 2
    static_x = np.nanmedian((static[:, 0] + static[:, 2]) / 2)
    if object_x >= static_x:
        static[:, 0] = np.where(np.isnan(static[:, 0]), np.nan, 0.0)
    else:
        static[:, 2] = np.where(np.isnan(static[:, 2]), np.nan, float(W))
    in_front = len(seen) > 0 and obj[seen[-1], 3] > np.nanmedian(static[:, 3])
    if rng.random() < 0.5 and not in_front:
        static[:, 3] = np.where(np.isnan(static[:, 3]), np.nan, float(H))
    return boxes, contact


def hand_partly_seen(boxes: np.ndarray, contact: np.ndarray, rng: np.random.Generator, image_size):
    """The hand has boxes in only 50-70 % of the frames: a window around the action phase
    (the hand enters late and leaves early, as real annotations of an arm coming in)."""
    boxes = boxes.copy()
    N = len(contact)
    on = np.flatnonzero(contact)
    first, last = (int(on[0]), int(on[-1])) if len(on) else (N // 3, 2 * N // 3)
    keep = max(int(round(rng.uniform(0.5, 0.7) * N)), last - first + 1)
    before = int(rng.integers(0, keep - (last - first + 1) + 1))
    start = int(np.clip(first - before, 0, N - keep))
    hidden = np.ones(N, bool)
    hidden[start : start + keep] = False
    boxes[0, hidden] = np.nan
    return boxes, contact


SPOILERS = {
    "stops_early": stops_early,
    "enters_view": enters_view,
    "static_cut_by_frame": static_cut_by_frame,
    "hand_partly_seen": hand_partly_seen,
}
"""The real videos' annotation situations, by name (see each function)."""


_CORNERS = ("x1", "y1", "x2", "y2")


def as_annotations(boxes: np.ndarray, contact: np.ndarray, video_id: str = "0", action: str | None = None,
                   nouns: Sequence[str | None] = ()):
    """Boxes (C, N, 4) [px] and an action phase (N,) as a Something-Else video, as the real files
    have it: frames without any box are absent from the file; ``object hand``, ``object 0`` and
    ``object <k + 1>`` labels, each with the ``category`` ``nouns`` gives it (the hand's
    ``hand``; none where ``nouns`` lacks one: a plain cuboid has none); approach / action /
    leave phases (1-based, inclusive).

    Returns:
        a :class:`~warpskill.data.boxes.something_else.SomethingElseVideo` for
        :func:`~warpskill.data.boxes.something_else.something_else_demonstration`.
    """
    labels = ["object hand", *(f"object {c}" for c in range(len(boxes) - 1))]
    categories = {"object hand": "hand", **{f"object {c}": noun for c, noun in enumerate(nouns) if noun}}
    frames = []
    for k in range(boxes.shape[1]):
        entries = [{"gt_annotation": label, "box2d": dict(zip(_CORNERS, box.tolist())),
                    **({"category": categories[label]} if nouns and label in categories else {})}
                   for label, box in zip(labels, boxes[:, k]) if not np.isnan(box).any()]
        if entries:
            frames.append({"name": f"{video_id}/{k + 1:04d}.jpg", "labels": entries})
    on = np.flatnonzero(contact)
    if not len(on):
        raise ValueError("contact: no frame in the action phase")
    spans = {"approach": (1, int(on[0])), "action": (int(on[0]) + 1, int(on[-1]) + 1),
             "leave": (int(on[-1]) + 2, len(contact))}
    phases = {name: (a, b) if a <= b else None for name, (a, b) in spans.items()}
    return SomethingElseVideo(video_id, frames, phases, action)
