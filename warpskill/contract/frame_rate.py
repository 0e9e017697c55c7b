"""The frames the optimiser fits: a fast video thinned to about the paper's frame rate.

The paper's videos (and the development videos) are 12 fps; a phone records 30 or 60. The
optimiser's physics runs at a fixed step whatever the frame rate, but stage (a), the
renderer and the mask losses cost per frame, and the contact filter's windows count
frames at 12 fps. :func:`frame_stride` picks the whole number of video frames per fitted
frame that brings the rate nearest :data:`OPTIMISER_FPS` (1, nothing dropped, below about
16 fps); :func:`every_nth` keeps every ``stride``-th frame, so each kept frame's time is
the video frame's own and the reconstruction's ``t`` stays on the video's clock.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import FIELD_SHAPES

__all__ = ["LEAST_FPS", "OPTIMISER_FPS", "at_optimiser_rate", "every_nth", "frame_stride", "kept_frames", "thinned_contact"]

OPTIMISER_FPS = 12.0
"""Frame rate [1/s] the optimiser is made for: that of the paper's and the development videos."""

LEAST_FPS = 9.5
"""Lowest frame rate [1/s] a video is thinned to (a 29.97 fps phone video: to 9.99)."""


def frame_stride(fps: float) -> int:
    """Video frames per fitted frame: the whole number s >= 1 whose rate fps / s is nearest
    :data:`OPTIMISER_FPS` by ratio without falling below :data:`LEAST_FPS` (30 fps: 3, so
    10 fps; 25: 2; 60: 5; 12, 15 and 18: 1)."""
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    ratio = fps / OPTIMISER_FPS
    low = max(1, math.floor(ratio))
    nearer_high = abs(math.log((low + 1) / ratio)) < abs(math.log(ratio / low))
    return low + 1 if nearer_high and fps / (low + 1) >= LEAST_FPS else low


def kept_frames(num_frames: int, stride: int) -> np.ndarray:
    """(M,) int indices of the video frames kept at ``stride``: 0, s, 2s, ... (the first frame always)."""
    if stride < 1:
        raise ValueError(f"stride must be at least 1, got {stride}")
    return np.arange(0, num_frames, stride)


def thinned_contact(contact: np.ndarray, stride: int) -> np.ndarray:
    """(N,) bool contact -> (M,) on the kept frames, each contact run kept as a run from the kept
    frame nearest its onset to the kept frame nearest its release (a tie: the wider run).

    So no run is lost (a run shorter than the stride keeps one frame) and an onset or a
    release moves by at most half a stride (a release in the video's last frames, after the
    last kept one, to that frame); off gaps shorter than the stride may close.
    """
    contact = np.asarray(contact, dtype=bool)
    out = np.zeros(len(kept_frames(len(contact), stride)), dtype=bool)
    edges = np.diff(np.concatenate([[False], contact, [False]]).astype(np.int8))
    for onset, end in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
        first = math.floor(onset / stride + 0.5 - 1e-9)  # half-way: the earlier kept frame
        last = min(math.floor((end - 1) / stride + 0.5), len(out) - 1)  # half-way: the later one
        out[first : last + 1] = True
    return out


def every_nth(demo: Demonstration, stride: int) -> Demonstration:
    """``demo`` on its :func:`kept_frames` at ``fps / stride``: masks and per-frame truth of the
    kept frames, the contact by :func:`thinned_contact`; ``demo`` itself for stride 1."""
    if stride == 1:
        return demo
    keep = kept_frames(demo.num_frames, stride)
    truth = {name: _thinned_field(name, value, keep, demo.fps / stride) for name, value in demo.truth.items()}
    return dataclasses.replace(
        demo, hand_mask=demo.hand_mask[keep], object_mask=demo.object_mask[keep],
        static_mask=demo.static_mask[:, keep], contact=thinned_contact(demo.contact, stride), fps=demo.fps / stride,
        truth=truth,
    )


def at_optimiser_rate(demo: Demonstration) -> Demonstration:
    """``demo`` on the frames the optimiser fits: :func:`every_nth` at :func:`frame_stride` of its
    rate (``demo`` itself at up to about 16 fps; thinning twice changes nothing)."""
    return every_nth(demo, frame_stride(demo.fps))


def _thinned_field(name: str, value: np.ndarray, keep: np.ndarray, fps: float) -> np.ndarray:
    """A truth field on the kept frames: per-frame ones (first axis N) sliced, ``fps`` the new rate."""
    if name == "fps":
        return np.float64(fps)
    return value[keep] if FIELD_SHAPES[name][:1] == ("N",) else value
