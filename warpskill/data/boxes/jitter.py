"""Box annotations moved at random by a few pixels: how much a verdict hangs on the annotator's hand.

:func:`jittered` moves every box corner of one Something-Else video
(:class:`~warpskill.data.boxes.something_else.SomethingElseVideo`) by up to a given number of
pixels, uniformly and independently in x and y; the copy goes through the same reader
(:func:`~warpskill.data.boxes.something_else.something_else_demonstration`) as the original.
:func:`video_rng` gives each video its own draw for a seed, the same on every run and in any
subset of videos.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import math
import numbers

import numpy as np

from warpskill.data.boxes.something_else import SomethingElseVideo

CORNERS = ("x1", "y1", "x2", "y2")
"""The coordinates of a ``box2d`` [px], each moved on its own."""


def jittered(video: SomethingElseVideo, px: float, rng: np.random.Generator) -> SomethingElseVideo:
    """A copy of ``video`` whose every box corner is moved by up to ``px`` [px] in x and in y.

    The offsets are uniform in [-px, px], drawn from ``rng`` in the order of the frames and
    their labels (four per box), so each frame gets its own. ``video`` is left as it is; a box
    whose ``box2d`` lacks a numeric corner is copied unmoved, for the reader to report. With
    ``px`` = 0 the boxes equal the original ones.

    Raises:
        ValueError: ``px`` negative or not finite.
    """
    if not math.isfinite(px) or px < 0:
        raise ValueError(f"jitter: expected a number of pixels >= 0, got {px}")
    frames = copy.deepcopy(video.frames)
    for entry in frames:
        for label in entry.get("labels", []) if isinstance(entry, dict) else []:
            box = label.get("box2d") if isinstance(label, dict) else None
            if _has_corners(box):
                for corner, offset in zip(CORNERS, rng.uniform(-px, px, size=len(CORNERS))):
                    box[corner] = float(box[corner]) + float(offset)
    return dataclasses.replace(video, frames=frames)


def video_rng(seed: int, video_id: str) -> np.random.Generator:
    """The random generator of one video's jitter: its own stream per (seed, video id)."""
    digest = hashlib.sha256(video_id.encode("utf-8")).digest()
    return np.random.default_rng([seed, int.from_bytes(digest[:8], "little")])


def _has_corners(box) -> bool:
    """Whether ``box`` is a dict with the four corners as real numbers (not booleans)."""
    return isinstance(box, dict) and all(
        isinstance(box.get(corner), numbers.Real) and not isinstance(box.get(corner), bool) for corner in CORNERS)
