"""Annotated real clips: a real-footage folder's frames and people's boxes per role.

A real-footage folder (``docs/formats.md``) holds ``frames/<id>/NNNN.jpg`` (numbered from
0001) and ``annotations.json``, Something-Else boxes per frame (:mod:`.something_else`).
:func:`read_footage` reads it clip by clip into :class:`FootageClip` records, each box
under its role (:func:`.something_else.scene_role`).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from warpskill.contract.demonstration import DemonstrationError
from warpskill.contract.vocabulary import role_order
from warpskill.data.boxes.something_else import read_box_annotations, scene_role
from warpskill.data.readers.video import read_video

ANNOTATIONS = "annotations.json"
"""The boxes' file in a real-footage folder."""


@dataclasses.dataclass(frozen=True)
class FootageClip:
    """One annotated real clip.

    Attributes:
        clip_id: the clip's id (its folder under ``frames/``).
        frames: (N, H, W, 3) uint8 RGB frames.
        boxes: role (``hand``, ``object``, ``static_0``, ...) -> (N, 4) boxes (x0, y0, x1,
            y1) [px], NaN in frames where the annotation does not box it.
        annotated: (N,) bool, frames the annotation covers (a frame without a hand box
            there is a frame where the annotators saw no hand).
        noun: the manipulated object's noun, or None.
    """

    clip_id: str
    frames: np.ndarray
    boxes: dict[str, np.ndarray]
    annotated: np.ndarray
    noun: str | None


def read_footage(folder: str | os.PathLike, clips: list[str] | None = None) -> list[FootageClip]:
    """The clips of a real-footage folder (all, or those named in ``clips``), in the file's order.

    Raises:
        FileNotFoundError: no ``annotations.json`` or no frames folder for a clip.
        DemonstrationError: an annotation file that is not ``{id: [frame entries]}``, a
            clip id it lacks, or a clip folder without frames ``0001.jpg``, ...
    """
    folder = Path(folder)
    annotations = read_box_annotations(folder / ANNOTATIONS)
    missing = sorted(set(clips or ()) - set(annotations))
    if missing:
        raise DemonstrationError(f"{folder / ANNOTATIONS}: no clip {', '.join(missing)}")
    return [_clip(folder, clip_id, annotations[clip_id]) for clip_id in (clips or list(annotations))]


def _clip(folder: Path, clip_id: str, entries: list[dict]) -> FootageClip:
    """One clip's frames and boxes."""
    frames, _ = read_video(folder / "frames" / clip_id / "%04d.jpg")
    n = len(frames)
    boxes: dict[str, np.ndarray] = {}
    annotated = np.zeros(n, dtype=bool)
    noun = None
    for entry in entries:
        k = int(Path(entry["name"]).stem) - 1
        if not 0 <= k < n:
            continue
        annotated[k] = True
        noun = noun or next(iter(entry.get("gt_placeholders") or []), None)
        for label in entry.get("labels", []):
            role = scene_role(label.get("gt_annotation", ""))
            if role is None:
                continue
            box = label["box2d"]
            boxes.setdefault(role, np.full((n, 4), np.nan))[k] = (box["x1"], box["y1"], box["x2"], box["y2"])
    boxes = {role: boxes[role] for role in sorted(boxes, key=role_order)}
    return FootageClip(clip_id, frames, boxes, annotated, noun)
