"""The errors real inputs have, put into exact masks: jittered boundaries, specks, dropped frames, boxes, off-by-one contact."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from warpskill.data.box_annotations import box_masks
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


def box_channels(masks: np.ndarray, noise: Noise, rng: np.random.Generator):
    """Ellipses inscribed in jittered boxes of each channel's visible silhouette, as box annotations give them."""
    N, C, H, W = masks.shape
    channels = []
    for c in range(C):
        boxes = np.full((N, 4), np.nan)
        for k in range(N):
            rows, cols = np.nonzero(masks[k, c])
            if len(rows) == 0:
                continue
            box = np.array([cols.min(), rows.min(), cols.max() + 1.0, rows.max() + 1.0])
            if noise.jitter:
                box = box + rng.integers(-noise.jitter, noise.jitter + 1, size=4)
            x1, y1, x2, y2 = np.clip(box, 0, [W, H, W, H])
            if x2 - x1 >= 1 and y2 - y1 >= 1:
                boxes[k] = x1, y1, x2, y2
        channels.append(box_masks(boxes, (H, W)))
    statics = channels[2:]
    return channels[0], channels[1], (np.stack(statics) if statics else None)


def phase_contact(script: Script, truth: dict[str, np.ndarray], masks: np.ndarray) -> np.ndarray:
    """An annotator's action phase: from the grasp onset to the release, or to ``script.phase_end``
    (clipped to the object's last visible frame), as a per-frame contact signal."""
    grasped = truth["grasped"] > 0.5
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
