"""How well the masks of a real clip stay on what people boxed: ``warpskill bench footage``.

A folder in the real-footage format (``frames/<id>/NNNN.jpg`` and ``annotations.json``,
Something-Else boxes per frame; ``docs/formats.md``) is read clip by clip
(:func:`warpskill.data.boxes.clips.read_footage`). Each clip is outlined as a hurried user would
(:func:`hurried_outline`: the object's and static objects' boxes, as rectangles, on the
middle frame that boxes both the hand and the object; the hand is not outlined), its masks
are made as ``warpskill run`` makes them, and each mask is compared with the annotators'
box in every frame that boxes it (:func:`warpskill.data.boxes.overlap.box_ious`: the IoU of
the mask's bounding box with the box; an empty mask counts 0).

With ``no_outline`` nobody outlines: the outline is proposed from the clip
(:func:`warpskill.data.footage.outline_proposal.propose_outline`, with the action
:func:`clip_action` and the annotation's noun, as a user gives them), and a clip where the
proposal is unsure is refused: it gets no masks (every boxed frame counts 0) and its line is
shown. The proposal's static objects are matched to the boxed ones (:func:`matched_statics`).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import time
from pathlib import Path

import cv2
import numpy as np

from warpskill.bench.outcomes import CaseOutcome, failed_case
from warpskill.bench.report import record_outcomes, show
from warpskill.contract.demonstration import DemonstrationError
from warpskill.contract.vocabulary import HAND, OBJECT, STATIC, role_kind
from warpskill.data.boxes.clips import FootageClip, read_footage
from warpskill.data.boxes.overlap import box_ious
from warpskill.data.footage.clip_masks import footage_masks
from warpskill.data.footage.outline_proposal import OutlineUnsure, proposal_picture, propose_outline
from warpskill.data.recording import IMAGE_SEQUENCE_FPS
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


PUT_ACTION, HOLD_ACTION = "put_onto", "pick_up"
"""The actions a clip is taken to show without an outline (the clips carry no action name):
one with a static object where the annotation boxes one, else one without."""


def clip_action(clip: FootageClip) -> str:
    """The action a user would name for ``clip`` as far as the outline goes: :data:`PUT_ACTION`
    where its annotation boxes a static object, else :data:`HOLD_ACTION`."""
    return PUT_ACTION if any(role_kind(role) == STATIC for role in clip.boxes) else HOLD_ACTION


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
        refused: why the clip got no masks (the proposed outline was unsure), or None.
    """

    ious: dict[str, np.ndarray]
    hand_free: int
    hand_free_masked: int
    contact_frames: int
    seconds: float
    refused: str | None = None


def score_clip(clip: FootageClip, hand: np.ndarray, objects: dict[str, np.ndarray], contact: np.ndarray,
               seconds: float, *, refused: str | None = None) -> ClipScores:
    """The box IoUs of a clip's masks (``hand`` (N, H, W), ``objects`` label -> (N, H, W));
    ``refused``: why it has none (empty masks given)."""
    ious = {}
    for role, boxes in clip.boxes.items():
        masks = hand if role == HAND else objects.get(role, np.zeros_like(hand))
        found = box_ious(masks, boxes)
        key = role_kind(role)
        ious[key] = np.concatenate([ious.get(key, np.zeros(0)), found[np.isfinite(found)]])
    free = clip.annotated & ~np.isfinite(clip.boxes.get(HAND, np.full((len(hand), 4), np.nan))[:, 0])
    masked = free & hand.reshape(len(hand), -1).any(axis=1)
    return ClipScores(ious, int(free.sum()), int(masked.sum()), int(np.sum(contact)), seconds, refused)


def bench_footage(folder: str | os.PathLike, out: str | os.PathLike | None = None, *, clips: list[str] | None = None,
                  baseline: str | os.PathLike | None = None, save_baseline: str | os.PathLike | None = None,
                  quiet: bool = False, no_outline: bool = False) -> dict[str, ClipScores]:
    """Each clip of a real-footage folder outlined as a hurried user would
    (:func:`hurried_outline`), or with ``no_outline`` its outline proposed from the clip
    (:func:`clip_outline`), its masks made as ``warpskill run`` makes them
    (:func:`warpskill.data.footage.clip_masks.footage_masks`), compared with the boxes; shows a
    table per clip and pooled, writes ``OUT/outcomes.json`` (a clip succeeds when every
    role is on its box in :data:`SHARE_TARGET` of its frames and the hand-free frames stay
    clear in :data:`CLEAR_TARGET`; a refused clip fails), with ``no_outline`` each proposal's
    picture ``OUT/proposals/<clip>.png``, and the flips since ``baseline``.

    Returns:
        clip id -> scores (refused clips included, with their reason).
    """
    scores, outcomes = {}, []
    for clip in progress_bar(read_footage(folder, clips), enabled=not quiet, desc="clips", unit="clip"):
        start = time.perf_counter()
        try:
            if no_outline:
                key_frame, key_masks, hands = clip_outline(clip, out)
            else:
                (key_frame, key_masks), hands = hurried_outline(clip), {}
            found = footage_masks(clip.frames, key_frame, key_masks, **hands)
        except OutlineUnsure as unsure:
            empty = np.zeros(clip.frames.shape[:3], dtype=bool)
            scores[clip.clip_id] = score_clip(clip, empty, {}, np.zeros(len(empty), dtype=bool),
                                              time.perf_counter() - start, refused=unsure.line)
            outcomes.append(failed_case(clip.clip_id, "footage", f"refused: {unsure.line}"))
            continue
        except DemonstrationError as error:
            outcomes.append(failed_case(clip.clip_id, "footage", str(error)))
            logger.warning("%s: %s", clip.clip_id, error)
            continue
        objects = matched_statics(clip, found.objects) if no_outline else found.objects
        scores[clip.clip_id] = score = score_clip(clip, found.found_hand, objects, found.contact,
                                                  time.perf_counter() - start)
        outcomes.append(_outcome(clip.clip_id, score))
    show(footage_table(scores))
    record_outcomes(out, outcomes, baseline=baseline, save_baseline=save_baseline)
    return scores


def clip_outline(clip: FootageClip, out: str | os.PathLike | None = None):
    """The outline proposed from ``clip`` (:func:`clip_action`, the annotation's noun, 12 fps),
    its picture written to ``out/proposals/<clip>.png`` when ``out`` is given.

    Returns:
        The outlined frame, label -> (H, W) bool masks, and the hands found
        (:func:`footage_masks`' ``tracks`` and ``regions``).

    Raises:
        OutlineUnsure: the proposal is unsure (its picture written all the same).
    """
    try:
        proposal = propose_outline(clip.frames, clip_action(clip), fps=IMAGE_SEQUENCE_FPS, object_noun=clip.noun)
    except OutlineUnsure as unsure:
        _save_picture(out, clip.clip_id, unsure.picture)
        raise
    _save_picture(out, clip.clip_id, proposal_picture(clip.frames[proposal.frame], proposal))
    return proposal.frame, proposal.masks(), {"tracks": proposal.tracks, "regions": proposal.regions}


def matched_statics(clip: FootageClip, objects: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The proposal's masks ``objects`` (label -> (N, H, W) bool) under the annotation's labels:
    the object as it is, and each static object the annotation boxes as the proposed static
    object whose masks fit its boxes best (highest mean box IoU). A proposal numbers its
    static objects in its own order, and one proposed static object may stand for two boxed
    ones (a puzzle and the part of it around the slot)."""
    proposed = [label for label in objects if role_kind(label) == STATIC]
    out = {label: mask for label, mask in objects.items() if role_kind(label) != STATIC}
    for role, boxes in clip.boxes.items():
        if role_kind(role) == STATIC and proposed:
            fits = [np.nan_to_num(np.nanmean(box_ious(objects[label], boxes))) for label in proposed]
            out[role] = objects[proposed[int(np.argmax(fits))]]
    return out


def _save_picture(out: str | os.PathLike | None, clip_id: str, picture: np.ndarray) -> None:
    """``picture`` (H, W, 3) uint8 RGB as ``out/proposals/<clip_id>.png`` (nothing without ``out``)."""
    if out is None:
        return
    folder = Path(out) / "proposals"
    folder.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(folder / f"{clip_id}.png"), cv2.cvtColor(picture, cv2.COLOR_RGB2BGR))


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
    lines += [f"{clip_id:>8} refused: {score.refused}" for clip_id, score in scores.items() if score.refused]
    return "\n".join(lines)
