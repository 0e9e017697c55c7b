"""One's own recording to a demonstration: a video file and one source of masks.

:func:`prepare_recording` reads the video with OpenCV, builds the masks from whichever
source is given (mask folders, label images, polygons on one frame propagated through the
video, or Something-Else boxes), settles the contact signal (a contact file as given;
detections or, lacking them, the masks through the paper's filter) and returns the
:class:`~warpskill.contract.Demonstration`. :func:`contact_sheet` draws what the optimiser
will see: the masks over sampled frames, with the contact flag of every frame.

Every error for bad input is a :class:`~warpskill.contract.DemonstrationError` (a
ValueError) whose one line names the file and the problem.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np

from warpskill.contract.actions import check_action
from warpskill.contract.demonstration import Demonstration, DemonstrationError
from warpskill.data.box_annotations import SomethingElseVideo, read_box_annotations, something_else_demonstration
from warpskill.data.contact import estimate_contact, read_detections
from warpskill.data.footage import footage_masks
from warpskill.data.masks import clean_masks
from warpskill.data.propagation import propagate_masks, read_polygons
from warpskill.data.readers import is_image_sequence, read_masks, read_video

SOURCES = ("masks", "labels", "polygons", "boxes")
"""The mask sources of :func:`prepare_recording`; exactly one is given."""

SHEET_TILES = 12
"""Frames drawn on the contact sheet (at most; evenly spaced, first and last included)."""

COLOURS = {"hand": (230, 60, 60), "object": (40, 200, 60), "static": (60, 120, 240)}
"""RGB of each role on the contact sheet."""

IMAGE_SEQUENCE_FPS = 12.0
"""Frame rate [1/s] taken for numbered image files without ``fps``: that of the frame
folders of Something-Something v2, the phone clips these come from most often."""

HAND_BONES = ((0, 1), (1, 2), (2, 3), (3, 4), (0, 5), (5, 6), (6, 7), (7, 8), (5, 9), (9, 10), (10, 11),
              (11, 12), (9, 13), (13, 14), (14, 15), (15, 16), (13, 17), (0, 17), (17, 18), (18, 19), (19, 20))
"""Pairs of hand landmarks joined when the found hand is drawn (MediaPipe's 21-point hand)."""


class Recording(NamedTuple):
    """A recording read as a demonstration.

    Attributes:
        demo: the demonstration.
        frames: (N, H, W, 3) uint8 RGB video frames.
        landmarks: (N, 21, 2) the found hand's landmarks (x, y) [px], NaN rows where none
            is seen; None when the hand was not found but given.
    """

    demo: Demonstration
    frames: np.ndarray
    landmarks: np.ndarray | None = None


def prepare_recording(video: str | os.PathLike, **sources) -> Demonstration:
    """A video and one source of masks as a demonstration: :func:`read_recording` (same
    keyword arguments) without the video's frames."""
    return read_recording(video, **sources).demo


def read_recording(
    video: str | os.PathLike,
    *,
    masks: str | os.PathLike | None = None,
    labels: str | os.PathLike | None = None,
    polygons: str | os.PathLike | None = None,
    boxes: str | os.PathLike | None = None,
    video_id: str | None = None,
    contact: str | os.PathLike | None = None,
    detections: str | os.PathLike | None = None,
    action: str,
    fps: float | None = None,
    intrinsics: tuple[float, float, float, float] | None = None,
    frame: int | None = None,
) -> Recording:
    """A video and one source of masks as a demonstration, and the video's frames.

    Args:
        video: a video file OpenCV can read, or numbered image files (``frames/%04d.jpg``);
            the masks are at its frames' size.
        masks: a folder of per-object mask folders (``hand/``, ``object/``, ``static*/``;
            :func:`warpskill.data.read_mask_folders`), one image per video frame.
        labels: a folder of label images, one per video frame
            (:func:`warpskill.data.read_label_images`, DAVIS convention).
        polygons: the polygons of one annotated frame (the polygon file of
            ``docs/formats.md`` or LabelMe; :func:`warpskill.data.read_polygons`),
            propagated through the video by optical flow
            (:func:`warpskill.data.propagate_masks`); without a hand polygon the hand is
            found in every frame, the objects followed and the contact read off the hand's
            landmarks (:func:`warpskill.data.footage.footage_masks`, extra ``video``).
        boxes: a Something-Else box annotations JSON (``{video_id: [frame entries]}``);
            each box becomes the ellipse inscribed in it.
        video_id: the video's id in ``boxes``; None when the file holds one video.
        contact: a contact CSV (:func:`read_contact`), one row per frame, used as given.
        detections: a contact detections CSV (:func:`warpskill.data.read_detections`),
            filtered as in the paper. With neither, contact is estimated from the masks.
        action: the action shown, one of :data:`warpskill.ACTIONS`.
        fps: frame rate [1/s]; None takes the video's (image files:
            :data:`IMAGE_SEQUENCE_FPS`).
        intrinsics: (fx, fy, cx, cy) [px] of the video's frames; None for the default of
            ``docs/formats.md`` (80 x 60 deg field of view).
        frame: the annotated frame of ``polygons``, overriding the file's (0-based).

    Returns:
        The demonstration (masks cleaned: the largest blob per frame; the object's noun from
        the polygon file's ``object_noun``), the frames and the found hand's landmarks.

    Raises:
        DemonstrationError: naming the file (or option) and the problem: not exactly one
            mask source, an unknown action, a video OpenCV cannot decode or without a frame
            rate, masks of another size or frame count, polygons outside the image or on
            a frame the video lacks, no hand found in any frame, an object lost in every
            frame, no boxes for ``video_id``, a contact file of the wrong length, a contact
            signal that is never on.
        FileNotFoundError: a file or folder does not exist.
    """
    source, where = _mask_source(dict(zip(SOURCES, (masks, labels, polygons, boxes))), contact=contact,
                                 detections=detections, video_id=video_id, frame=frame, action=action)
    frames, fps = _frames(video, fps)
    camera_K = _camera_matrix(intrinsics)
    hand, obj, static, found, noun = _masks(source, where, video, frames, frame=frame, video_id=video_id, action=action)
    signal = _contact(contact, detections, found, hand, obj, video, where)
    try:
        demo = Demonstration.from_arrays(
            hand, obj, signal, fps, static_mask=np.stack(static) if static else None, camera_K=camera_K, action=action,
            object_noun=noun,
        )
    except DemonstrationError as exc:
        raise DemonstrationError(f"{contact if contact is not None else where}: {exc}") from None
    return Recording(demo, frames, None if found is None else found.landmarks)


def _mask_source(sources: dict, *, contact, detections, video_id, frame, action: str) -> tuple[str, object]:
    """The one mask source given among ``sources`` (name -> path or None), as (name, path); the
    options checked against it."""
    given = {name: value for name, value in sources.items() if value is not None}
    if len(given) != 1:
        names = ", ".join(given) if given else "none"
        raise DemonstrationError(f"give exactly one mask source of {', '.join(SOURCES)} (got {names})")
    if contact is not None and detections is not None:
        raise DemonstrationError("give a contact file or a detections file, not both")
    if video_id is not None and "boxes" not in given:
        raise DemonstrationError("video_id: only with boxes")
    if frame is not None and "polygons" not in given:
        raise DemonstrationError("frame: only with polygons")
    try:
        check_action(action)
    except ValueError as exc:
        raise DemonstrationError(f"action: {exc}") from None
    [(source, where)] = given.items()
    return source, where


def _frames(video, fps: float | None) -> tuple[np.ndarray, float]:
    """The video's frames (N, H, W, 3) and its frame rate [1/s]: ``fps``, else the video's own."""
    frames, video_fps = read_video(video)
    if fps is None:
        fps = IMAGE_SEQUENCE_FPS if is_image_sequence(video) else video_fps
    if not fps or not np.isfinite(fps) or fps <= 0:
        raise DemonstrationError(f"{video}: declares no frame rate; give fps" if not fps else f"fps: must be > 0, got {fps}")
    return frames, fps


def _masks(source: str, where, video, frames: np.ndarray, *, frame: int | None, video_id: str | None, action: str):
    """Hand (N, H, W), object (N, H, W) and static [(N, H, W)] masks of the mask source, cleaned, the
    found hand (or None) and the object's noun (or None)."""
    n, h, w = frames.shape[:3]
    found, noun = None, None
    if source in ("masks", "labels"):
        if source == "masks" and not (Path(where) / "hand").is_dir():
            raise FileNotFoundError(f"{where}: no hand/ folder (--masks reads hand/, object/, static*/ folders)")
        hand, obj, static = read_masks(where)
    elif source == "polygons":
        key_frame, key_masks, noun = read_polygons(where, (h, w), frame=frame)
        if key_frame >= n:
            raise DemonstrationError(f"{where}: frame {key_frame} is not in {video}, which has frames 0..{n - 1}")
        if "hand" in key_masks:
            propagated = propagate_masks(frames, key_frame, key_masks)
        else:
            found = _found(video, frames, key_frame, key_masks)
            propagated = {"hand": found.hand, **found.objects}
        hand, obj = propagated.pop("hand"), propagated.pop("object")
        static = list(propagated.values())
    else:
        hand, obj, static = _box_masks(where, video_id, n, (h, w), action)
    if hand.shape != (n, h, w):
        raise DemonstrationError(
            f"{where}: masks of {hand.shape[0]} frames of {hand.shape[2]} x {hand.shape[1]} (W x H) px, "
            f"but {video} has {n} frames of {w} x {h} px"
        )
    hand, obj = clean_masks(hand), clean_masks(obj)
    static = [clean_masks(mask) for mask in static]
    for name, mask in (("hand", hand), ("object", obj)):
        if not mask.any():
            raise DemonstrationError(f"{where}: the {name} mask is empty in every frame")
    return hand, obj, static, found, noun


def _contact(contact, detections, found, hand: np.ndarray, obj: np.ndarray, video, where) -> np.ndarray:
    """(N,) the contact signal: the contact file's, the found hand's, or estimated from the masks
    (and the detections file)."""
    n = len(hand)
    if contact is not None:
        return read_contact(contact, n)
    if found is not None and detections is None:
        if not found.contact.any():
            raise DemonstrationError(f"{video}: no fingertip touches the object in any frame; give a contact file")
        return found.contact
    signal = estimate_contact(hand, obj, detections=None if detections is None else read_detections(detections, n))
    if not signal.any():
        origin = detections if detections is not None else f"{where} (estimated from the masks)"
        raise DemonstrationError(f"{origin}: the contact signal is never on; give a contact file")
    return signal


def _found(video, frames: np.ndarray, key_frame: int, key_masks: dict[str, np.ndarray]):
    """:func:`~warpskill.data.footage.footage_masks`; an error naming the video where no hand is
    found in any frame or an outlined object is lost in every frame."""
    found = footage_masks(frames, key_frame, key_masks)
    if not found.hand.any():
        raise DemonstrationError(
            f"{video}: no hand found in any of its {len(frames)} frames; outline the hand on one frame (hand key)"
        )
    lost = [label for label, masks in found.objects.items() if not masks.any()]
    if lost:
        raise DemonstrationError(
            f"{video}: {', '.join(lost)} lost in every frame; outline it on a frame where it is well visible"
        )
    return found


def read_contact(path: str | os.PathLike, num_frames: int) -> np.ndarray:
    """Read a contact CSV: a header row with the column ``contact`` (0/1 or true/false) and
    optionally ``frame`` (then 0, 1, 2, ... in order), one row per video frame.

    Returns:
        (N,) bool.

    Raises:
        DemonstrationError: naming the file (and line), for a missing column, a value that
            is not 0/1, frames out of order, or a row count other than ``num_frames``.
        FileNotFoundError: ``path`` does not exist.
    """
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        columns = [name.strip() for name in reader.fieldnames or ()]
        if "contact" not in columns:
            raise DemonstrationError(f"{path}: no 'contact' column; expected a header row 'frame,contact' (or 'contact')")
        values = []
        for row in reader:
            row = {key.strip(): (value or "").strip() for key, value in row.items() if key is not None}
            where = f"{path}, line {reader.line_num}"
            if "frame" in columns and row.get("frame") != str(len(values)):
                raise DemonstrationError(f"{where}: frame {row.get('frame')!r}, expected {len(values)} (one row per frame, in order)")
            text = row.get("contact", "").lower()
            if text not in ("0", "1", "true", "false"):
                raise DemonstrationError(f"{where}: contact {row.get('contact')!r}: expected 0/1 or true/false")
            values.append(text in ("1", "true"))
    if len(values) != num_frames:
        raise DemonstrationError(f"{path}: {len(values)} contact rows, but the video has {num_frames} frames")
    return np.array(values, dtype=bool)


def contact_sheet(
    demo: Demonstration, frames: np.ndarray | None, path: str | os.PathLike, landmarks: np.ndarray | None = None
) -> Path:
    """Draw the masks over sampled frames with each frame's contact flag, and a strip of the
    contact signal of every frame; write it as a PNG (OpenCV).

    Args:
        demo: the demonstration.
        frames: its (N, H, W, 3) uint8 RGB video frames, or None to draw on grey.
        path: the PNG to write.
        landmarks: (N, 21, 2) the found hand's landmarks [px] (NaN rows where none), drawn
            as a skeleton; None draws none.

    Returns:
        ``path``.

    Raises:
        ValueError: ``frames`` disagree with the demonstration's frame count or size.
    """
    n, (h, w) = demo.num_frames, demo.image_size
    if frames is None:
        frames = np.full((n, h, w, 3), 96, dtype=np.uint8)
    frames = np.asarray(frames)
    if frames.shape != (n, h, w, 3):
        raise ValueError(f"frames: expected shape {(n, h, w, 3)} for the demonstration, got {frames.shape}")
    scale = float(np.clip(240.0 / w, 1.0, None)) if w < 240 else min(1.0, 320.0 / w)
    tile_w, tile_h = int(round(w * scale)), int(round(h * scale))
    header, gap = 18, 4
    picks = np.unique(np.round(np.linspace(0, n - 1, min(n, SHEET_TILES))).astype(int))
    columns = min(4, len(picks))
    rows = -(-len(picks) // columns)
    width = columns * (tile_w + gap) + gap
    strip_h = 44
    sheet = np.full((rows * (tile_h + header + gap) + gap + strip_h, width, 3), 255, dtype=np.uint8)
    for index, k in enumerate(picks):
        tile = _overlay(demo, frames, int(k))
        if landmarks is not None:
            _skeleton(tile, landmarks[k])
        tile = cv2.resize(tile, (tile_w, tile_h), interpolation=cv2.INTER_NEAREST if scale > 1 else cv2.INTER_AREA)
        y = gap + (index // columns) * (tile_h + header + gap)
        x = gap + (index % columns) * (tile_w + gap)
        on = bool(demo.contact[k])
        sheet[y : y + header, x : x + tile_w] = (250, 170, 30) if on else (70, 70, 70)
        text = f"frame {k}  " + ("contact" if on else "no contact")
        cv2.putText(sheet, text, (x + 4, y + header - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0) if on else (255, 255, 255), 1, cv2.LINE_AA)
        sheet[y + header : y + header + tile_h, x : x + tile_w] = tile
    _strip(sheet, demo, picks, sheet.shape[0] - strip_h, gap)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR)):
        raise OSError(f"{path}: OpenCV could not write the contact sheet")
    return path


def _overlay(demo: Demonstration, frames: np.ndarray, k: int) -> np.ndarray:
    """Frame ``k`` with each mask tinted in its role's colour and outlined."""
    tile = frames[k].astype(np.float32)
    layers = [("static", mask[k]) for mask in demo.static_mask] + [("object", demo.object_mask[k]), ("hand", demo.hand_mask[k])]
    for role, mask in layers:
        tile[mask] = 0.55 * tile[mask] + 0.45 * np.array(COLOURS[role], dtype=np.float32)
    tile = tile.astype(np.uint8)
    for role, mask in layers:
        contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(tile, contours, -1, COLOURS[role], 1)
    return tile


def _skeleton(tile: np.ndarray, points: np.ndarray) -> None:
    """The found hand's landmarks (21, 2) [px] drawn on ``tile`` in place (nothing for NaN)."""
    if not np.isfinite(points).all():
        return
    pixel = np.round(points * 16 - 8).astype(np.int32)
    for a, b in HAND_BONES:
        cv2.line(tile, tuple(pixel[a]), tuple(pixel[b]), (255, 255, 255), 1, cv2.LINE_AA, shift=4)
    for point in pixel:
        cv2.circle(tile, tuple(point), 2 * 16, (255, 230, 0), -1, cv2.LINE_AA, shift=4)


def _strip(sheet: np.ndarray, demo: Demonstration, picks: np.ndarray, top: int, gap: int) -> None:
    """The contact signal of every frame along the bottom of ``sheet``, the drawn frames ticked, and the legend."""
    n, width = demo.num_frames, sheet.shape[1] - 2 * gap
    edges = np.round(np.linspace(gap, gap + width, n + 1)).astype(int)
    for k in range(n):
        colour = (250, 170, 30) if demo.contact[k] else (215, 215, 215)
        sheet[top + 4 : top + 16, edges[k] : max(edges[k + 1] - 1, edges[k] + 1)] = colour
    for k in picks:
        sheet[top + 17 : top + 21, edges[k] : max(edges[k + 1] - 1, edges[k] + 1)] = 0
    x = gap
    for label, colour in (("hand", COLOURS["hand"]), ("object", COLOURS["object"]), ("static", COLOURS["static"]),
                          ("contact", (250, 170, 30))):
        sheet[top + 27 : top + 39, x : x + 12] = colour
        cv2.putText(sheet, label, (x + 16, top + 38), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        x += 22 + 8 * len(label)
    on = np.flatnonzero(demo.contact)
    summary = f"{n} frames, {demo.fps:g} fps, contact in {len(on)}"
    cv2.putText(sheet, summary, (x + 10, top + 38), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)


def _camera_matrix(intrinsics) -> np.ndarray | None:
    """(fx, fy, cx, cy) as K, or None."""
    if intrinsics is None:
        return None
    values = np.asarray(intrinsics, dtype=float)
    if values.shape != (4,) or not np.isfinite(values).all() or values[0] <= 0 or values[1] <= 0:
        raise DemonstrationError(f"intrinsics: expected fx fy cx cy with fx, fy > 0 [px], got {list(np.ravel(intrinsics))}")
    fx, fy, cx, cy = values
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def _box_masks(path, video_id: str | None, num_frames: int, image_size: tuple[int, int], action: str):
    """Hand, object and static masks of one video's Something-Else boxes, over ``num_frames`` frames."""
    annotations = read_box_annotations(path)
    if video_id is None:
        if len(annotations) != 1:
            raise DemonstrationError(f"{path}: holds {len(annotations)} videos; give the video id")
        [video_id] = annotations
    if str(video_id) not in annotations:
        raise DemonstrationError(f"{path}: no boxes for video id {video_id!r}")
    # The contact settled here is a placeholder (the whole video): the caller replaces it.
    phases = {"approach": None, "action": (1, num_frames), "leave": None}
    entry = SomethingElseVideo(str(video_id), annotations[str(video_id)], phases, action)
    try:
        demo, _ = something_else_demonstration(entry, image_size=image_size)
    except DemonstrationError as exc:
        raise DemonstrationError(f"{path}: {exc}") from None
    if demo.num_frames > num_frames:
        raise DemonstrationError(f"{path}: video {video_id} has boxes up to frame {demo.num_frames}, the video only {num_frames} frames")
    return demo.hand_mask, demo.object_mask, list(demo.static_mask)
