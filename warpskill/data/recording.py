"""One's own recording to a demonstration: a video file and at most one source of masks.

:func:`prepare_recording` reads the video with OpenCV, builds the masks from whichever
source is given (mask folders, label images, polygons on one frame propagated through the
video, or Something-Else boxes; with none, the polygons proposed from the video itself,
:func:`warpskill.data.footage.outline_proposal.propose_outline`), settles the contact
signal (a contact file as given; detections or, lacking them, the masks through the paper's
filter) and returns the :class:`~warpskill.contract.Demonstration`; :func:`read_recording`
also returns the frames and the found hand's landmarks (for
:func:`warpskill.visual.sheet.contact_sheet`). It joins the three pipelines of
:mod:`warpskill.data`: the readers, the boxes and the footage path.

Every error for bad input is a :class:`~warpskill.contract.DemonstrationError` (a
ValueError) whose one line names the file and the problem.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from warpskill.contract.actions import check_action
from warpskill.contract.demonstration import Demonstration, DemonstrationError
from warpskill.contract.vocabulary import HAND, OBJECT
from warpskill.data.boxes.something_else import SomethingElseVideo, read_box_annotations, something_else_demonstration
from warpskill.data.contact import estimate_contact
from warpskill.data.footage.clip_masks import footage_masks
from warpskill.data.footage.outline_proposal import OutlineProposal, propose_outline
from warpskill.data.footage.propagation import propagate_masks
from warpskill.data.masks import clean_masks
from warpskill.data.readers.contact_files import read_contact, read_detections
from warpskill.data.readers.mask_files import read_masks
from warpskill.data.readers.polygons import read_polygons
from warpskill.data.readers.video import is_image_sequence, read_video

MASK_SOURCES = ("masks", "labels", "polygons", "boxes")
"""The mask sources of :func:`prepare_recording`; at most one is given (none: the outline is proposed)."""

PROPOSED = "proposed"
"""The mask source where none is given: the outline proposed from the video, followed as polygons are."""

IMAGE_SEQUENCE_FPS = 12.0
"""Frame rate [1/s] taken for numbered image files without ``fps``: that of the frame
folders of Something-Something v2, the phone clips these come from most often."""


class Recording(NamedTuple):
    """A recording read as a demonstration.

    Attributes:
        demo: the demonstration.
        frames: (N, H, W, 3) uint8 RGB video frames.
        landmarks: (N, 21, 2) the found hand's landmarks (x, y) [px], NaN rows where none
            is seen; None when the hand was not found but given.
        outline: the outline proposed from the video where no mask source was given, else None.
    """

    demo: Demonstration
    frames: np.ndarray
    landmarks: np.ndarray | None = None
    outline: OutlineProposal | None = None


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
    object_noun: str | None = None,
    static_noun: str | None = None,
) -> Recording:
    """A video and at most one source of masks as a demonstration, and the video's frames.

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
        object_noun: what the manipulated object is (overrides the polygon file's); with no
            mask source also a size prior of the proposed outline.
        static_noun: what the (first) static object is; with no mask source also a size prior.

    With no mask source the outline is proposed from the video (:func:`propose_outline`:
    the object the hand takes, the static object of a ``put_*`` action) and followed as
    ``polygons`` are.

    Returns:
        The demonstration (masks cleaned: the largest blob per frame; the object's noun from
        ``object_noun``, else the polygon file's ``object_noun``), the frames, the found
        hand's landmarks and the proposed outline.

    Raises:
        OutlineUnsure: no mask source and the video does not say what to outline (its line
            says what; it carries a picture of what was seen).
        DemonstrationError: naming the file (or option) and the problem: more than one
            mask source, an unknown action, a video OpenCV cannot decode or without a frame
            rate, masks of another size or frame count, polygons outside the image or on
            a frame the video lacks, no hand found in any frame, an object lost in every
            frame, no boxes for ``video_id``, a contact file of the wrong length, a contact
            signal that is never on.
        FileNotFoundError: a file or folder does not exist.
    """
    source, where = _mask_source(dict(zip(MASK_SOURCES, (masks, labels, polygons, boxes))), contact=contact,
                                 detections=detections, video_id=video_id, frame=frame, action=action)
    frames, fps = _frames(video, fps)
    camera_K = _camera_matrix(intrinsics)
    outline = None
    if source == PROPOSED:
        outline = propose_outline(frames, action, fps=fps, object_noun=object_noun, static_noun=static_noun)
        where = f"{video} (the proposed outline)"
    hand, obj, static, found, noun = _masks(source, where, video, frames, frame=frame, video_id=video_id, action=action,
                                            outline=outline)
    if static_noun is not None and not static:
        raise DemonstrationError(f"static_noun: {where} has no static object")
    signal = _contact(contact, detections, found, hand, obj, video, where)
    try:
        demo = Demonstration.from_arrays(
            hand, obj, signal, fps, static_mask=np.stack(static) if static else None, camera_K=camera_K, action=action,
            object_noun=object_noun or noun, static_nouns=(static_noun,) + (None,) * (len(static) - 1) if static else (),
        )
    except DemonstrationError as exc:
        raise DemonstrationError(f"{contact if contact is not None else where}: {exc}") from None
    return Recording(demo, frames, None if found is None else found.landmarks, outline)


def _mask_source(sources: dict, *, contact, detections, video_id, frame, action: str) -> tuple[str, object]:
    """The mask source given among ``sources`` (name -> path or None), as (name, path), or
    (:data:`PROPOSED`, None) for none; the options checked against it."""
    given = {name: value for name, value in sources.items() if value is not None}
    if len(given) > 1:
        raise DemonstrationError(f"give at most one mask source of {', '.join(MASK_SOURCES)} (got {', '.join(given)})")
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
    return next(iter(given.items()), (PROPOSED, None))


def _frames(video, fps: float | None) -> tuple[np.ndarray, float]:
    """The video's frames (N, H, W, 3) and its frame rate [1/s]: ``fps``, else the video's own."""
    frames, video_fps = read_video(video)
    if fps is None:
        fps = IMAGE_SEQUENCE_FPS if is_image_sequence(video) else video_fps
    if not fps or not np.isfinite(fps) or fps <= 0:
        raise DemonstrationError(f"{video}: declares no frame rate; give fps" if not fps else f"fps: must be > 0, got {fps}")
    return frames, fps


def _masks(source: str, where, video, frames: np.ndarray, *, frame: int | None, video_id: str | None, action: str,
           outline: OutlineProposal | None):
    """Hand (N, H, W), object (N, H, W) and static [(N, H, W)] masks of the mask source (or of
    the proposed ``outline``), cleaned, the found hand (or None) and the object's noun (or None)."""
    n, h, w = frames.shape[:3]
    found, noun = None, None
    if source in ("masks", "labels"):
        if source == "masks" and not (Path(where) / "hand").is_dir():
            raise FileNotFoundError(f"{where}: no hand/ folder (--masks reads hand/, object/, static*/ folders)")
        hand, obj, static = read_masks(where)
    elif source in ("polygons", PROPOSED):
        hands = {}
        if source == PROPOSED:
            key_frame, key_masks, noun = outline.frame, outline.masks(), outline.nouns.get(OBJECT)
            hands = {"tracks": outline.tracks, "regions": outline.regions}
        else:
            key_frame, key_masks, noun = read_polygons(where, (h, w), frame=frame)
        if key_frame >= n:
            raise DemonstrationError(f"{where}: frame {key_frame} is not in {video}, which has frames 0..{n - 1}")
        if HAND in key_masks:
            propagated = propagate_masks(frames, key_frame, key_masks)
        else:
            found = _found(video, frames, key_frame, key_masks, **hands)
            propagated = {HAND: found.hand, **found.objects}
        hand, obj = propagated.pop(HAND), propagated.pop(OBJECT)
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
    for name, mask in ((HAND, hand), (OBJECT, obj)):
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


def _found(video, frames: np.ndarray, key_frame: int, key_masks: dict[str, np.ndarray], **hands):
    """:func:`~warpskill.data.footage.clip_masks.footage_masks` (``hands``: its ``tracks`` and
    ``regions`` when already found); an error naming the video where no hand is found in any
    frame or an outlined object is lost in every frame."""
    found = footage_masks(frames, key_frame, key_masks, **hands)
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
