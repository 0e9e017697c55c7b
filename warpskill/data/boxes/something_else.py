"""Something-Else bounding-box annotations and Real2Sim action phases into demonstrations.

The data (the development set's ``README.md``): per-frame boxes labelled
``object hand``, ``object 0`` (the manipulated object) and ``object 1`` (the static
object) in a JSON file; ``approach``, ``action``, ``leave`` phases at 12 fps as 1-based,
inclusive frame ranges (``-`` = absent) in a CSV; action names in another CSV.

**Box to mask.** Each box becomes the ellipse inscribed in it (:data:`BOX_SHAPES`). On the
model's own cuboid and cylinder silhouettes the inscribed ellipse and the full box match
the true mask about equally well (docs/results-history.md), while most real objects here
(plate, mug, cup, bowl, glove, the hand itself) are rounded, which the ellipse follows and
the box's corners overshoot.

**Messy annotations**, each reported in the per-video notes:

- a label other than ``object hand`` / ``object <k>``: a box whose category is ``hand`` is
  the hand, one whose category is the k-th placeholder is ``object k``; others are dropped;
- ``object k`` with k >= 1 is static object k - 1;
- two or more boxes of one label in a frame: the one nearest (centre distance) to that
  label's box in the closest frame with a single box is kept (the largest when there is
  none);
- a label missing in up to :data:`MAX_GAP` frames between two frames that have it: its box
  is interpolated linearly; longer gaps, and frames before the first / after the last box,
  are "not visible" (empty mask); frames absent from the file are handled the same way;
- boxes are clipped to the image; empty or degenerate boxes, and boxes with a NaN
  coordinate, are dropped;
- the demonstration ends at the last frame the annotations list: frames after it, even
  where the phases go on, carry no evidence (an annotation that stops while the hand holds
  the object up does not say the object fell), so they are left out and the phases
  clipped to it; absent frames before it are frames without boxes.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import re

import numpy as np

from warpskill.contract.actions import check_action
from warpskill.contract.demonstration import Demonstration, DemonstrationError
from warpskill.contract.vocabulary import HAND, OBJECT, static_role

FPS = 12.0
"""Frame rate of the annotations [1/s]."""

IMAGE_SIZE = (240, 427)
"""(H, W) of the original frames [px]."""

BOX_SHAPES = ("ellipse", "rectangle")
"""Mask drawn for a box: the inscribed ellipse (default) or the full rectangle."""

MAX_GAP = 2
"""Longest run of frames [frames] in which a missing box is interpolated."""

PHASES = ("approach", "action", "leave")

HAND_LABEL = "object hand"
"""The label of the hand's boxes; the objects' are ``object k`` (:func:`object_index`)."""

_FRAME_NAME = re.compile(r"(?:^|/)(\d+)\.\w+$")
_OBJECT_LABEL = re.compile(r"^object (\d+)$")


def object_index(label: str) -> int | None:
    """k of a box labelled ``object k`` (0: the manipulated object, k >= 1: static object
    k - 1); None for any other label."""
    match = _OBJECT_LABEL.match(label)
    return None if match is None else int(match.group(1))


def scene_role(label: str) -> str | None:
    """The role (:mod:`warpskill.contract.vocabulary`) of a box label: ``object hand`` ->
    ``hand``, ``object 0`` -> ``object``, ``object k`` -> ``static_{k-1}``; None for any other."""
    if label == HAND_LABEL:
        return HAND
    k = object_index(label)
    return None if k is None else OBJECT if k == 0 else static_role(k - 1)


@dataclasses.dataclass
class SomethingElseVideo:
    """One annotated video, as read from the files (not yet checked for completeness).

    Attributes:
        video_id: the video's id.
        frames: the JSON's per-frame entries (``name``, ``labels``, ``gt_placeholders``), or
            an empty list when the annotations lack the video.
        phases: phase name -> (first, last) 1-based inclusive frames, or None when absent;
            None when the phases CSV lacks the video.
        action: the action name, or None when unknown.
    """

    video_id: str
    frames: list[dict]
    phases: dict[str, tuple[int, int] | None] | None
    action: str | None


def read_something_else(
    annotations: str | os.PathLike, phases: str | os.PathLike, actions: str | os.PathLike | None = None
) -> dict[str, SomethingElseVideo]:
    """Read the three files; every video named in any of them gets an entry.

    Args:
        annotations: the Something-Else JSON ``{video_id: [frame entries]}``.
        phases: CSV with columns ``video_id, approach, action, leave``.
        actions: CSV with columns ``video_id, action``, or None.

    Returns:
        video id -> :class:`SomethingElseVideo`, sorted by id.

    Raises:
        DemonstrationError: naming the file and the video / line, for a file that is not
            JSON / CSV of this layout, a bad phase range or an unknown action name.
        FileNotFoundError: a file does not exist.
    """
    boxes = read_box_annotations(annotations)
    phase_rows = _read_csv(phases, ("video_id", *PHASES))
    phase_table = {vid: {name: _phase(phases, line, row[name]) for name in PHASES} for vid, (line, row) in phase_rows.items()}
    action_table = {}
    if actions is not None:
        for vid, (line, row) in _read_csv(actions, ("video_id", "action")).items():
            try:
                action_table[vid] = check_action((row["action"] or "").strip())
            except ValueError as exc:
                raise DemonstrationError(f"{actions}, line {line}: {exc}") from None
    ids = sorted(set(boxes) | set(phase_table) | set(action_table), key=lambda vid: (len(vid), vid))
    return {
        vid: SomethingElseVideo(vid, boxes.get(vid, []), phase_table.get(vid), action_table.get(vid)) for vid in ids
    }


def read_box_annotations(path: str | os.PathLike) -> dict[str, list]:
    """The Something-Else JSON ``{video_id: [frame entries]}`` at ``path``, its layout checked.

    Raises:
        DemonstrationError: naming the file, for a file that is not UTF-8 JSON of that layout.
        FileNotFoundError: ``path`` does not exist.
    """
    with open(path, encoding="utf-8-sig") as handle:
        try:
            boxes = json.load(handle)
        except json.JSONDecodeError as exc:
            raise DemonstrationError(f"{path}: not valid JSON ({exc})") from None
        except UnicodeDecodeError as exc:
            raise DemonstrationError(f"{path}: not UTF-8 text ({exc})") from None
    if not isinstance(boxes, dict) or not all(isinstance(frames, list) for frames in boxes.values()):
        raise DemonstrationError(f"{path}: expected an object {{video_id: [frame entries]}}")
    return boxes


def something_else_demonstration(
    video: SomethingElseVideo, *, shape: str = "ellipse", image_size: tuple[int, int] = IMAGE_SIZE
) -> tuple[Demonstration, list[str]]:
    """Masks from the boxes, contact from the ``action`` phase.

    Args:
        video: one entry of :func:`read_something_else`.
        shape: one of :data:`BOX_SHAPES`.
        image_size: (H, W) of the frames the boxes are in [px].

    Returns:
        The demonstration (at :data:`FPS`, the default intrinsics, its ``object_noun`` from
        :func:`object_noun`) and the notes: one sentence per deliberate choice about messy
        annotations (see the module docstring).

    Raises:
        DemonstrationError: naming the video: no annotations, no phases or no ``action``
            phase, a malformed frame entry, no hand or object box at all, or an unknown
            ``shape``.
    """
    where = f"video {video.video_id}"
    if shape not in BOX_SHAPES:
        raise DemonstrationError(f"shape: expected one of {BOX_SHAPES}, got {shape!r}")
    if not video.frames:
        raise DemonstrationError(f"{where}: no box annotations")
    if video.phases is None or video.phases["action"] is None:
        raise DemonstrationError(f"{where}: no action phase, so no contact signal")
    notes: list[str] = []
    tracks = _tracks(video, where, notes)
    num_frames = _annotated_length(video, notes)
    _note_absent_frames(video, num_frames, notes)
    for role in ("hand", "object 0"):
        if not tracks.get(role):
            raise DemonstrationError(f"{where}: no '{'object hand' if role == 'hand' else role}' box in any frame")
    h, w = image_size
    masks = {}
    for role, track in tracks.items():
        boxes = _fill_gaps(_clip(track, (h, w), role, notes), num_frames, role, notes)
        masks[role] = np.stack([_box_mask(box, (h, w), shape) for box in boxes])
    first, last = video.phases["action"]
    if last > num_frames:
        notes.append(f"action phase {first}-{last} ends after the last frame {num_frames}: clipped")
    contact = np.zeros(num_frames, dtype=bool)
    contact[first - 1 : last] = True
    statics = sorted((role for role in masks if role not in ("hand", "object 0")), key=object_index)
    static_mask = np.stack([masks[role] for role in statics]) if statics else None
    try:
        demo = Demonstration.from_arrays(
            masks["hand"], masks["object 0"], contact, FPS, static_mask=static_mask, action=video.action,
            object_noun=object_noun(video), static_nouns=[role_noun(video, role) for role in statics],
        )
    except DemonstrationError as exc:
        raise DemonstrationError(f"{where}: {exc}") from None
    return demo, notes


def object_noun(video: SomethingElseVideo) -> str | None:
    """What the manipulated object is called (:func:`role_noun` of ``object 0``)."""
    return role_noun(video, "object 0")


def role_noun(video: SomethingElseVideo, role: str) -> str | None:
    """What the object labelled ``role`` (``object k``) is called: the placeholder for it (the
    k-th noun of the video's label), else the ``category`` of its boxes; None when neither is given."""
    k = object_index(role)
    for entry in video.frames:
        placeholders = entry.get("gt_placeholders") if isinstance(entry, dict) else None
        if placeholders and len(placeholders) > k and isinstance(placeholders[k], str) and placeholders[k].strip():
            return placeholders[k].strip()
    for entry in video.frames:
        for label in entry.get("labels", []) if isinstance(entry, dict) else []:
            category = label.get("category") if isinstance(label, dict) else None
            if label.get("gt_annotation") == role and isinstance(category, str) and category.strip():
                return category.strip()
    return None


def box_masks(boxes: np.ndarray, image_size: tuple[int, int], shape: str = "ellipse") -> np.ndarray:
    """Rasterise boxes: a pixel is set when its centre lies in the shape.

    Args:
        boxes: (N, 4) float (x1, y1, x2, y2) [px, continuous image coordinates]; NaN rows
            give empty masks.
        image_size: (H, W).
        shape: one of :data:`BOX_SHAPES`.

    Returns:
        (N, H, W) bool.
    """
    if shape not in BOX_SHAPES:
        raise ValueError(f"shape: expected one of {BOX_SHAPES}, got {shape!r}")
    return np.stack([_box_mask(box, image_size, shape) for box in np.asarray(boxes, dtype=float)])


# --------------------------------------------------------------------------- boxes per label


def _tracks(video: SomethingElseVideo, where: str, notes: list[str]) -> dict[str, dict[int, np.ndarray]]:
    """Role ("hand", "object k") -> {1-based frame: (4,) box}, one box per frame."""
    candidates: dict[str, dict[int, list[np.ndarray]]] = {}
    for index, entry in enumerate(video.frames):
        try:
            frame = _frame_number(entry)
            if frame < 1:
                raise DemonstrationError(f"{where}: frame entry {index}: frame number {frame} in {entry['name']!r}, "
                                         "but frames are numbered from 1")
            placeholders = list(entry.get("gt_placeholders", []))
            for label in entry["labels"]:
                role = _role(label, placeholders, frame, notes)
                if role is not None:
                    box = label["box2d"]
                    box = np.array([box["x1"], box["y1"], box["x2"], box["y2"]], dtype=float)
                    candidates.setdefault(role, {}).setdefault(frame, []).append(box)
        except DemonstrationError:
            raise
        except (KeyError, TypeError, AttributeError, ValueError) as exc:
            detail = f"missing key {exc}" if isinstance(exc, KeyError) else "unexpected layout"
            raise DemonstrationError(f"{where}: frame entry {index}: {detail}") from None
    tracks = {}
    for role, frames in candidates.items():
        single = {frame: boxes[0] for frame, boxes in frames.items() if len(boxes) == 1}
        multiple = sorted(frame for frame, boxes in frames.items() if len(boxes) > 1)
        track = dict(single)
        for frame in multiple:
            track[frame] = _pick(frames[frame], single, frame)
        if multiple:
            notes.append(f"{role}: several boxes in frame(s) {_ranges(multiple)}: kept the one nearest its track")
        tracks[role] = track
    return tracks


def _role(label: dict, placeholders: list[str], frame: int, notes: list[str]) -> str | None:
    """The role of one box label, or None to drop it (with a note for anything unexpected)."""
    name, category = str(label["gt_annotation"]), str(label.get("category", ""))
    if name == HAND_LABEL:
        return "hand"
    if object_index(name) is not None:
        return name
    if category == "hand":
        role = "hand"
    elif category in placeholders:
        role = f"object {placeholders.index(category)}"
    else:
        notes.append(f"frame {frame}: dropped a box labelled {name!r} ({category!r}), not a hand or placeholder")
        return None
    notes.append(f"frame {frame}: box labelled {name!r} ({category!r}) read as {role!r} by its category")
    return role


def _pick(boxes: list[np.ndarray], single: dict[int, np.ndarray], frame: int) -> np.ndarray:
    """Of several boxes, the one nearest the label's box in the closest single-box frame (else the largest)."""
    if single:
        reference = single[min(single, key=lambda other: abs(other - frame))]
        return min(boxes, key=lambda box: np.linalg.norm(_centre(box) - _centre(reference)))
    return max(boxes, key=lambda box: (box[2] - box[0]) * (box[3] - box[1]))


def _clip(track: dict[int, np.ndarray], image_size, role: str, notes: list[str]) -> dict[int, np.ndarray]:
    """Boxes clipped to the image; empty ones and those with a NaN coordinate dropped (noted)."""
    h, w = image_size
    clipped, dropped = {}, []
    for frame, box in track.items():
        x1, y1, x2, y2 = np.clip(box, 0, [w, h, w, h])
        if np.isnan(box).any() or x2 - x1 < 1 or y2 - y1 < 1:
            dropped.append(frame)
        else:
            clipped[frame] = np.array([x1, y1, x2, y2])
    if dropped:
        notes.append(f"{role}: dropped empty, non-finite or out-of-image boxes in frame(s) {_ranges(dropped)}")
    return clipped


def _fill_gaps(track: dict[int, np.ndarray], num_frames: int, role: str, notes: list[str]) -> np.ndarray:
    """(N, 4) boxes by 0-based frame: short inner gaps interpolated, other missing frames NaN."""
    boxes = np.full((num_frames, 4), np.nan)
    for frame, box in track.items():
        boxes[frame - 1] = box
    frames = sorted(track)
    filled = []
    for before, after in zip(frames, frames[1:]):
        if 1 < after - before <= MAX_GAP + 1:
            for frame in range(before + 1, after):
                t = (frame - before) / (after - before)
                boxes[frame - 1] = (1 - t) * track[before] + t * track[after]
                filled.append(frame)
    if filled:
        notes.append(f"{role}: missing box interpolated in frame(s) {_ranges(filled)}")
    unseen = np.flatnonzero(np.isnan(boxes[:, 0])) + 1
    if len(unseen):
        notes.append(f"{role}: no box in frame(s) {_ranges(unseen.tolist())}: not visible there")
    return boxes


def _annotated_length(video: SomethingElseVideo, notes: list[str]) -> int:
    """N, the last frame the annotations list (1-based); notes phase frames cut off after it."""
    num_frames = max(_frame_number(entry) for entry in video.frames)
    last_phase = max(span[1] for span in video.phases.values() if span is not None)
    if last_phase > num_frames:
        notes.append(f"frame(s) {_ranges(list(range(num_frames + 1, last_phase + 1)))} of the phases are after the "
                     f"annotations' last frame {num_frames}: the demonstration ends there")
    return num_frames


def _frame_number(entry: dict) -> int:
    """The 1-based frame number of a JSON frame entry (its ``name``, ``<video_id>/<frame>.jpg``)."""
    return int(_FRAME_NAME.search(entry["name"]).group(1))


def _note_absent_frames(video: SomethingElseVideo, num_frames: int, notes: list[str]) -> None:
    """Note the frames of 1..N that have no entry in the annotations."""
    listed = {_frame_number(entry) for entry in video.frames}
    absent = sorted(set(range(1, num_frames + 1)) - listed)
    if absent:
        notes.append(f"frame(s) {_ranges(absent)} not in the annotations: treated as frames without boxes")


def _box_mask(box: np.ndarray, image_size: tuple[int, int], shape: str) -> np.ndarray:
    """(H, W) bool: pixels whose centre lies in the box's rectangle or inscribed ellipse."""
    h, w = image_size
    if np.isnan(box).any():
        return np.zeros((h, w), dtype=bool)
    x1, y1, x2, y2 = box
    u = (np.arange(w) + 0.5 - (x1 + x2) / 2) / ((x2 - x1) / 2)
    v = (np.arange(h) + 0.5 - (y1 + y2) / 2) / ((y2 - y1) / 2)
    if shape == "rectangle":
        return (np.abs(v)[:, None] <= 1) & (np.abs(u)[None, :] <= 1)
    return v[:, None] ** 2 + u[None, :] ** 2 <= 1


# --------------------------------------------------------------------------- files


def _read_csv(path: str | os.PathLike, columns: tuple[str, ...]) -> dict[str, tuple[int, dict]]:
    """video_id -> (line number, row) of a CSV with at least ``columns``."""
    rows = {}
    with open(path, newline="", encoding="utf-8-sig") as handle:
        reader = csv.DictReader(handle)
        try:
            missing = set(columns) - set(reader.fieldnames or ())
            if missing:
                raise DemonstrationError(f"{path}: missing column(s) {', '.join(sorted(missing))}")
            for row in reader:
                vid = (row["video_id"] or "").strip()
                if vid in rows:
                    raise DemonstrationError(f"{path}, line {reader.line_num}: video {vid} listed twice")
                rows[vid] = (reader.line_num, row)
        except UnicodeDecodeError as exc:
            raise DemonstrationError(f"{path}: not UTF-8 text ({exc})") from None
        except csv.Error as exc:
            raise DemonstrationError(f"{path}, line {reader.line_num}: not a readable CSV row ({exc})") from None
    return rows


def _phase(path, line: int, text: str | None) -> tuple[int, int] | None:
    """'a-b' -> (a, b) with 1 <= a <= b; '-' -> None."""
    text = (text or "").strip()
    if text == "-":
        return None
    match = re.fullmatch(r"(\d+)-(\d+)", text)
    if not match or not 1 <= int(match.group(1)) <= int(match.group(2)):
        raise DemonstrationError(f"{path}, line {line}: phase {text!r}: expected 'first-last' (1-based) or '-'")
    return int(match.group(1)), int(match.group(2))


def _centre(box: np.ndarray) -> np.ndarray:
    return np.array([box[0] + box[2], box[1] + box[3]]) / 2


def _ranges(frames: list[int]) -> str:
    """[1, 2, 3, 7] -> '1-3, 7'."""
    spans, start = [], frames[0]
    for prev, cur in zip(frames, [*frames[1:], None]):
        if cur != prev + 1:
            spans.append(f"{start}-{prev}" if prev > start else f"{start}")
            start = cur
    return ", ".join(spans)
