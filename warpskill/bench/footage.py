"""How well the masks of a real clip stay on what people boxed: ``warpskill bench footage``.

A folder in the real-footage format (``frames/<id>/NNNN.jpg`` and ``annotations.json``,
Something-Else boxes per frame; ``docs/formats.md``) is read clip by clip
(:func:`warpskill.data.boxes.clips.read_footage`). Each clip is outlined as a hurried user would
(:func:`hurried_outline`: the object's and static objects' boxes, as rectangles, on the
middle frame that boxes both the hand and the object; the hand is not outlined), its masks
are made as ``warpskill run`` makes them, and each mask is compared with the annotators'
box in every frame that boxes it (:func:`warpskill.data.boxes.overlap.box_ious`: the IoU of
the mask's bounding box with the box; an empty mask counts 0).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import time

import numpy as np

from warpskill.bench.outcomes import CaseOutcome, failed_case
from warpskill.bench.report import record_outcomes, show
from warpskill.contract.demonstration import DemonstrationError
from warpskill.contract.vocabulary import HAND, OBJECT, STATIC, role_kind
from warpskill.data.boxes.clips import FootageClip, read_footage
from warpskill.data.boxes.overlap import box_ious
from warpskill.data.footage.clip_masks import footage_masks
from warpskill.progress import progress_bar

logger = logging.getLogger(__name__)

SAME_OBJECT_IOU = 0.5
"""Box IoU from which a mask counts as on its object (the usual detection threshold)."""


def hurried_outline(clip: FootageClip) -> tuple[int, dict[str, np.ndarray]]:
    """The outline a hurried user draws: on the middle frame that boxes both the hand and the
    object, the object's and every static object's box (boxed there) as rectangles.

    Returns:
        The frame index and label (``object``, ``static_0``, ...) -> (H, W) bool mask.

    Raises:
        DemonstrationError: no frame boxes both the hand and the object.
    """
    both = np.isfinite(clip.boxes.get(HAND, np.full((len(clip.frames), 4), np.nan))[:, 0])
    both &= np.isfinite(clip.boxes[OBJECT][:, 0]) if OBJECT in clip.boxes else False
    candidates = np.flatnonzero(both)
    if not len(candidates):
        candidates = np.flatnonzero(np.isfinite(clip.boxes[OBJECT][:, 0])) if OBJECT in clip.boxes else candidates
    if not len(candidates):
        raise DemonstrationError(f"clip {clip.clip_id}: no frame boxes the object")
    frame = int(candidates[len(candidates) // 2])
    h, w = clip.frames.shape[1:3]
    masks = {}
    for role, boxes in clip.boxes.items():
        if role == HAND or not np.isfinite(boxes[frame, 0]):
            continue
        x0, y0, x1, y1 = np.clip(boxes[frame], 0, [w, h, w, h])
        mask = np.zeros((h, w), dtype=bool)
        mask[int(round(y0)) : int(round(y1)), int(round(x0)) : int(round(x1))] = True
        if mask.any():
            masks[role] = mask
    return frame, masks


SHARE_TARGET = 0.85
"""Share of boxed frames a clip's masks should be on their box in (IoU >= :data:`SAME_OBJECT_IOU`)."""

CLEAR_TARGET = 0.90
"""Share of hand-free frames that should get no hand mask."""


@dataclasses.dataclass(frozen=True)
class ClipScores:
    """How one clip's masks match its boxes.

    Attributes:
        ious: role (``hand``, ``object``, ``static``) -> box IoUs of its boxed frames (all
            static objects pooled under ``static``).
        hand_free: annotated frames without a hand box.
        hand_free_masked: how many of them were given a hand mask.
        contact_frames: frames whose contact is on.
        seconds: the time the masks took [s].
    """

    ious: dict[str, np.ndarray]
    hand_free: int
    hand_free_masked: int
    contact_frames: int
    seconds: float


def score_clip(clip: FootageClip, hand: np.ndarray, objects: dict[str, np.ndarray], contact: np.ndarray,
               seconds: float) -> ClipScores:
    """The box IoUs of a clip's masks (``hand`` (N, H, W), ``objects`` label -> (N, H, W))."""
    ious = {}
    for role, boxes in clip.boxes.items():
        masks = hand if role == HAND else objects.get(role, np.zeros_like(hand))
        found = box_ious(masks, boxes)
        key = role_kind(role)
        ious[key] = np.concatenate([ious.get(key, np.zeros(0)), found[np.isfinite(found)]])
    free = clip.annotated & ~np.isfinite(clip.boxes.get(HAND, np.full((len(hand), 4), np.nan))[:, 0])
    masked = free & hand.reshape(len(hand), -1).any(axis=1)
    return ClipScores(ious, int(free.sum()), int(masked.sum()), int(np.sum(contact)), seconds)


def bench_footage(folder: str | os.PathLike, out: str | os.PathLike | None = None, *, clips: list[str] | None = None,
                  baseline: str | os.PathLike | None = None, save_baseline: str | os.PathLike | None = None,
                  quiet: bool = False) -> dict[str, ClipScores]:
    """Each clip of a real-footage folder outlined as a hurried user would
    (:func:`hurried_outline`), its masks made as ``warpskill run`` makes them
    (:func:`warpskill.data.footage.clip_masks.footage_masks`), compared with the boxes; shows a
    table per clip and pooled, writes ``OUT/outcomes.json`` (a clip succeeds when every
    role is on its box in :data:`SHARE_TARGET` of its frames and the hand-free frames stay
    clear in :data:`CLEAR_TARGET`) and the flips since ``baseline``.

    Returns:
        clip id -> scores.
    """
    scores, outcomes = {}, []
    for clip in progress_bar(read_footage(folder, clips), enabled=not quiet, desc="clips", unit="clip"):
        start = time.perf_counter()
        try:
            key_frame, key_masks = hurried_outline(clip)
            found = footage_masks(clip.frames, key_frame, key_masks)
        except DemonstrationError as error:
            outcomes.append(failed_case(clip.clip_id, "footage", str(error)))
            logger.warning("%s: %s", clip.clip_id, error)
            continue
        scores[clip.clip_id] = score = score_clip(clip, found.found_hand, found.objects, found.contact,
                                                  time.perf_counter() - start)
        outcomes.append(_outcome(clip.clip_id, score))
    show(footage_table(scores))
    record_outcomes(out, outcomes, baseline=baseline, save_baseline=save_baseline)
    return scores


def _outcome(clip_id: str, score: ClipScores) -> CaseOutcome:
    """A clip's row of the outcome table: the roles off their boxes too often are its failed checks."""
    shares = {f"{role}_on_box": float(np.mean(ious >= SAME_OBJECT_IOU)) for role, ious in score.ious.items() if len(ious)}
    if score.hand_free:
        shares["hand_free_clear"] = 1.0 - score.hand_free_masked / score.hand_free
    failed = tuple(name for name, share in shares.items()
                   if share < (CLEAR_TARGET if name == "hand_free_clear" else SHARE_TARGET))
    return CaseOutcome(clip_id, "footage", not failed, failed, shares)


def footage_table(scores: dict[str, ClipScores]) -> str:
    """Per clip and pooled over all frames: each role's median box IoU and share >= 0.5,
    the hand-free frames given a hand mask, contact frames and seconds."""
    roles = (HAND, OBJECT, STATIC)
    header = f"{'clip':>8} " + " ".join(f"{role + ' med / >=0.5':>22}" for role in roles)
    lines = [header + f" {'hand-free masked':>17} {'contact':>8} {'s':>6}"]

    def cells(ious_of: dict[str, np.ndarray]) -> str:
        out = []
        for role in roles:
            ious = ious_of.get(role, np.zeros(0))
            out.append(f"{np.median(ious):.2f} / {np.mean(ious >= SAME_OBJECT_IOU):4.0%} ({len(ious):3d})"
                       if len(ious) else "-")
        return " ".join(f"{cell:>22}" for cell in out)

    for clip_id, score in scores.items():
        lines.append(f"{clip_id:>8} {cells(score.ious)} {score.hand_free_masked:>7d} of {score.hand_free:<6d}"
                     f" {score.contact_frames:>8d} {score.seconds:6.2f}")
    pooled = {role: np.concatenate([s.ious.get(role, np.zeros(0)) for s in scores.values()]) for role in roles}
    free = sum(s.hand_free for s in scores.values())
    masked = sum(s.hand_free_masked for s in scores.values())
    seconds = [s.seconds for s in scores.values()]
    lines.append(f"{'all':>8} {cells(pooled)} {masked:>7d} of {free:<6d} {'':>8} "
                 f"{np.median(seconds) if seconds else float('nan'):6.2f} (median)")
    return "\n".join(lines)
