"""The demonstration as both stages fit it: masks at the working resolution, their moments, the filtered contact."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.signals import majority_filter
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.losses import MaskTargets


@dataclass
class WorkingInputs:
    """What both stages fit, at the working resolution.

    Attributes:
        intrinsics: the camera at the working resolution.
        masks: (N, 2 + K, h, w) area-averaged masks: hand, object, statics.
        targets: ``masks`` with their moments, for the dIoU; the hand and the object, where
            drawn from boxes (:func:`drawn_from_boxes`), compare boxes.
        contact_signal: (N,) bool, the majority-filtered contact.
        contact: (N,) the same as floats on the device.
        object_visible: (N,) 1 where the object's mask is not empty.
        hand_boxed: the hand's masks are drawn from boxes (:func:`drawn_from_boxes`): their
            width says nothing of the hand's depth, and only their boxes are compared.
    """

    intrinsics: object
    masks: torch.Tensor
    targets: MaskTargets
    contact_signal: np.ndarray
    contact: torch.Tensor
    object_visible: torch.Tensor
    hand_boxed: bool


def working_inputs(demo: Demonstration, config: OptimizeConfig, device: torch.device) -> WorkingInputs:
    """The demonstration's masks and contact as the optimiser uses them (see :class:`WorkingInputs`)."""
    h, w = demo.intrinsics.scaled(config.image_scale).image_size
    masks = torch.as_tensor(demo.mask_stack(h, w), device=device)
    contact_signal = majority_filter(demo.contact)
    contact_signal = contact_signal | carried_into_view(masks.cpu().numpy(), contact_signal)
    # The hand and the object drawn from boxes are compared by their boxes: a cuboid that
    # fills the ellipse in an object's box by area is smaller (and lower) than the object.
    # Static boxes keep the area fit: annotators' static boxes are partly amodal (they keep
    # what the object covers), and comparing their boxes placed the object worse
    # (docs/results-history.md).
    boxed = torch.zeros(masks.shape[1], dtype=torch.bool, device=device)
    boxed[:2] = torch.tensor([drawn_from_boxes(np.asarray(m, dtype=bool)) for m in (demo.hand_mask, demo.object_mask)])
    hand_boxed = bool(boxed[0])
    absent = torch.as_tensor(out_of_sight(masks.cpu().numpy()), device=device)
    return WorkingInputs(
        intrinsics=demo.intrinsics.resized(h, w),
        masks=masks,
        targets=MaskTargets(masks, boxed, absent),
        contact_signal=contact_signal,
        contact=torch.as_tensor(contact_signal, dtype=torch.float32, device=device),
        object_visible=(masks[:, 1].flatten(1).amax(1) > 0.5).float(),
        hand_boxed=hand_boxed,
    )


def out_of_sight(masks: np.ndarray, *, min_run: int = 3) -> np.ndarray:
    """(N, C) bool: frames in which a cuboid's part is known to be out of sight.

    Once seen, the object's and the static boxes' masks (channels 1...) may vanish because
    the part is hidden behind another one or has left the image, or because a segmenter
    lost it for a frame. Runs of at least ``min_run`` empty frames after the part was first
    seen are taken for the former. Before it is first seen, a part may be anywhere (carried
    into the view, or not yet annotated): no evidence. The hand (channel 0) is left free: it
    enters and leaves the view with the arm, at no pace the masks tell.

    Args:
        masks: (N, C, h, w) masks in [0, 1].
    """
    N, C = masks.shape[:2]
    empty = ~(masks > 0.5).reshape(N, C, -1).any(-1)
    out = np.zeros((N, C), dtype=bool)
    for c in range(1, C):
        if empty[:, c].all():
            continue
        k = int(np.flatnonzero(~empty[:, c])[0])
        while k < N:
            if not empty[k, c]:
                k += 1
                continue
            end = k
            while end < N and empty[end, c]:
                end += 1
            if end - k >= min_run:
                out[k:end, c] = True
            k = end
    return out


def drawn_from_boxes(masks: np.ndarray, *, tolerance: float = 0.05, min_share: float = 0.8) -> bool:
    """Whether masks (N, H, W) are shapes drawn inside boxes (box annotations), not segmentations.

    A frame's mask counts as drawn from a box when it differs from the ellipse inscribed in
    its bounds, or from the bounds themselves, in at most ``tolerance`` of their union plus
    a quarter of the box's perimeter [px] (rasterisation at the edge); the masks are, when
    at least ``min_share`` of the non-empty frames do.
    """
    H, W = masks.shape[-2:]
    rows, cols = np.arange(H)[:, None] + 0.5, np.arange(W)[None] + 0.5
    matched = total = 0
    for mask, box in zip(masks, _boxes(masks)):
        if np.isnan(box[0]):
            continue
        total += 1
        u0, v0, u1, v1 = box + np.array([0, 0, 1, 1])
        rectangle = np.zeros_like(mask)
        rectangle[int(v0) : int(v1), int(u0) : int(u1)] = True
        ellipse = ((cols - 0.5 * (u0 + u1)) / (0.5 * (u1 - u0))) ** 2 + ((rows - 0.5 * (v0 + v1)) / (0.5 * (v1 - v0))) ** 2 <= 1
        allowed = 0.5 * ((u1 - u0) + (v1 - v0))
        matched += any((shape ^ mask).sum() <= tolerance * (shape | mask).sum() + allowed for shape in (ellipse, rectangle))
    return bool(total > 0 and matched >= min_share * total)


def _boxes(masks: np.ndarray) -> np.ndarray:
    """(N, 4) pixel bounds (col0, row0, col1, row1) of each mask (N, h, w) bool; NaN when empty."""
    out = np.full((len(masks), 4), np.nan)
    for k, mask in enumerate(masks):
        rows, cols = np.nonzero(mask)
        if len(rows):
            out[k] = cols.min(), rows.min(), cols.max(), rows.max()
    return out


STEADY_SIZE = 0.1
"""How far a static box's width and height may stray from their medians (a share of them) in
a frame that measures the camera's motion (:func:`static_box_drift`): farther, and something
covers part of the static object, or the image's border cuts it."""


def static_box_drift(masks: np.ndarray) -> float:
    """[px] How far the static objects' boxes wander over a video: per static box, the diagonal
    of the range its centre covers over the frames where it is whole (off the image's borders)
    and of steady size (:data:`STEADY_SIZE`); the largest of them, 0 without a static box.

    Static objects do not move, so a box that does while keeping its size says the camera
    moved (a phone in a hand), which the reconstruction's fixed camera cannot follow.

    Args:
        masks: (N, 2 + K, h, w) masks in [0, 1]: hand, object, statics.
    """
    h, w = masks.shape[-2:]
    drift = 0.0
    for k in range(2, masks.shape[1]):
        boxes = _boxes(masks[:, k] > 0.5)
        whole = np.isfinite(boxes).all(1)
        inside = (boxes[whole, 0] > 0) & (boxes[whole, 1] > 0) & (boxes[whole, 2] < w - 1) & (boxes[whole, 3] < h - 1)
        whole[whole] = inside
        if not whole.any():
            continue
        sizes = boxes[whole, 2:] - boxes[whole, :2]
        steady = (np.abs(sizes / np.median(sizes, 0) - 1.0) <= STEADY_SIZE).all(1)
        centres = 0.5 * (boxes[whole][steady, :2] + boxes[whole][steady, 2:])
        if len(centres):
            drift = max(drift, float(np.hypot(*np.ptp(centres, 0))))
    return drift


def carried_into_view(masks: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """(N,) bool: the frames before the contact signal's onset in which the object is already held.

    An object that first appears at the image border after the video's first frame entered
    the view, and objects do not move by themselves: the hand brought it in, holding it from
    the first frame, even when annotators start the contact only once the hand is in view
    (or once the object is put down). These are the frames before the onset; elsewhere
    nothing is returned.

    Args:
        masks: (N, 2 + K, h, w) masks in [0, 1]: hand, object, statics.
        contact: (N,) bool.
    """
    N = len(contact)
    out = np.zeros(N, dtype=bool)
    on = np.flatnonzero(contact)
    seen = np.flatnonzero((masks[:, 1] > 0.5).reshape(N, -1).any(-1))
    if len(on) == 0 or len(seen) == 0 or seen[0] == 0:
        return out
    h, w = masks.shape[-2:]
    u0, v0, u1, v1 = _boxes(masks[seen[0] : seen[0] + 1, 1] > 0.5)[0]
    if u0 <= 0 or v0 <= 0 or u1 >= w - 1 or v1 >= h - 1:
        out[: on[0]] = True
    return out


def held_after_contact(masks: np.ndarray, contact: np.ndarray, *, min_frames: int = 2,
                       moved_share: float = 0.25, moved_px: float = 3.0, touch_share: float = 0.2,
                       border_share: float = 0.01) -> np.ndarray:
    """(N,) bool: frames after the contact signal's end in which the object may still be held.

    Annotators may end the action phase while the hand still holds the object: it is then
    seen in the air with the hand on it, or it leaves the view with the hand. These are
    the frames from the last contact frame to the video's end when nothing after it says
    the hand let go, and something says it did not:

    - in a frame with a hand box, the object's box (the bounds of its mask) touches the
      hand's, to within ``touch_share`` of its larger side: a box apart from the hand's says
      the hand let go (an object brought toward the camera hides the hand's tip, and the
      hand's box can end a few pixels short of it);
    - frames without a hand box are missing evidence, not a release (the hand may have
      left the annotation, or the view, with the object in it), but the object must show
      it was carried there: in at least ``min_frames`` of them its box's bottom row moved
      since the contact's end (by more than ``moved_share`` of its larger side and
      ``moved_px``), and objects do not move by themselves; or it hangs where the hand
      lifted it, away from the static boxes (:func:`_lifted_off`): an object let go in the
      air falls;
    - an object that leaves the view after it last touched the image border (to within
      ``border_share`` of the frame's larger side: a drawn box may stop a pixel or two short
      of it) in contact with the hand (or with no hand box) left with the hand; one that
      vanishes in the middle of the image was not.

    Read them at the masks' own resolution: a small object's mask, averaged down, can fade
    below one half in the frames where the hand covers most of it and seem to vanish there.

    Whether it is really held there is for the physics to decide (see
    :func:`warpskill.optimize`); elsewhere, and when the run does not reach the video's
    end, nothing is returned.

    Args:
        masks: (N, 2 + K, h, w) masks in [0, 1]: hand, object, statics.
        contact: (N,) bool.
        min_frames: fewer such frames than this are ignored.
        moved_share, moved_px: how far [share of the box's larger side, px] the object's
            box must move in frames without a hand box to count as carried (both: a few
            pixels of an annotator's jitter are no motion).
        touch_share: the gap between the object's and the hand's boxes that still counts
            as touching [share of the object box's larger side; at least 1 px].
        border_share: how close to the image border [share of the frame's larger side; at
            least 1 px] a box counts as touching it.
    """
    N = len(contact)
    out = np.zeros(N, dtype=bool)
    on = np.flatnonzero(contact)
    if len(on) == 0 or on[-1] > N - 1 - min_frames:
        return out
    h, w = masks.shape[-2:]
    hand, obj = _boxes(masks[:, 0] > 0.5), _boxes(masks[:, 1] > 0.5)
    visible, hand_seen = ~np.isnan(obj[:, 0]), ~np.isnan(hand[:, 0])
    with np.errstate(invalid="ignore"):
        near = np.maximum(touch_share * np.maximum(obj[:, 2] - obj[:, 0], obj[:, 3] - obj[:, 1]), 1.0)
        attached = ((hand[:, 0] <= obj[:, 2] + near) & (obj[:, 0] <= hand[:, 2] + near)
                    & (hand[:, 1] <= obj[:, 3] + near) & (obj[:, 1] <= hand[:, 3] + near))
        edge = max(border_share * max(h, w), 1.0)
        at_border = visible & ((obj[:, 0] <= edge) | (obj[:, 1] <= edge)
                               | (obj[:, 2] >= w - 1 - edge) | (obj[:, 3] >= h - 1 - edge))
    end = on[-1]
    seen = np.flatnonzero(visible[: end + 1])
    gone = False
    if not visible[end]:  # the object left the view before the signal ended
        if len(seen) == 0 or not at_border[seen[-1]]:
            return out
        gone = True
    released_box = obj[seen[-1]] if len(seen) else None
    unseen_hand, moves, carried = False, 0, False
    for k in range(end + 1, N):
        if visible[k]:
            if hand_seen[k] and not attached[k]:
                return out
            if not hand_seen[k]:
                unseen_hand = True
                moves += released_box is not None and _moved(released_box, obj[k], moved_share, moved_px)
            gone = False
        elif not gone:
            if not (at_border[k - 1] and (attached[k - 1] or contact[k - 1] or not hand_seen[k - 1])):
                return out
            carried |= not hand_seen[k - 1]  # it left the view: it moved
            gone = True
    lifted = _lifted_off(obj, visible, on, moved_share, moved_px) and not _beside_static(
        obj, [_boxes(masks[:, 2 + k] > 0.5) for k in range(masks.shape[1] - 2)], on)
    if carried or moves >= min_frames or not unseen_hand or lifted:
        out[end + 1 :] = True
    return out


def _beside_static(boxes: np.ndarray, statics: list[np.ndarray], on: np.ndarray, gap: float = 2.0) -> bool:
    """Whether the object's box (``boxes`` (N, 4) [px]) at its last contact frame where it is
    seen comes within ``gap`` [px] of a static's box there: a static can hide its bottom, so
    its rise says nothing."""
    during = on[~np.isnan(boxes[on, 0])]
    if not len(during):
        return False
    o, k = boxes[during[-1]], during[-1]
    return any(not np.isnan(s[k, 0]) and s[k, 0] <= o[2] + gap and o[0] <= s[k, 2] + gap
               and s[k, 1] <= o[3] + gap and o[1] <= s[k, 3] + gap for s in statics)


def _lifted_off(boxes: np.ndarray, visible: np.ndarray, on: np.ndarray, share: float, floor: float) -> bool:
    """Whether the hand lifted the object and did not set it down: from its last box before the
    contact to its last box in it, its box's bottom row rose by more than the box's own height
    (and ``floor`` [px]; a push away from the camera raises it by less), and over the contact's
    last third it came down from its highest by no more than ``share`` of its larger side
    (and ``floor``): a put sets it down. ``boxes`` (N, 4) [px], ``visible`` (N,) bool, ``on``
    the contact frames."""
    before = np.flatnonzero(visible[: on[0] + 1])
    during = on[visible[on]]
    if not len(before) or not len(during):
        return False
    start, end = boxes[before[-1]], boxes[during[-1]]
    rise = start[3] - end[3]
    last_third = during[during >= on[0] + 2 * (on[-1] - on[0]) // 3]
    came_down = end[3] - boxes[last_third, 3].min()
    size = max(end[2] - end[0], end[3] - end[1])
    return bool(rise > max(end[3] - end[1], floor) and came_down <= max(share * size, floor))


def _moved(before: np.ndarray, after: np.ndarray, share: float, floor: float) -> bool:
    """Whether box ``after`` (4,)'s bottom row differs from ``before``'s by more than ``share``
    of ``before``'s larger side and ``floor`` [px]. The bottom row, because a hand that moves
    away from a released object uncovers its top and sides, seldom its bottom."""
    return bool(abs(after[3] - before[3]) > max(share * max(before[2] - before[0], before[3] - before[1]), floor))


def rests_on_static(masks: np.ndarray, contact: np.ndarray, *, min_frames: int = 2) -> np.ndarray:
    """(N,) bool: frames after the release in which the object may rest on the first static box.

    The paper's Fig. 1: an object released over a static box is either on its top or behind
    it on the ground, and one view cannot tell. It may be on top when, in at least 80 % of the
    frames from the release to the video's end (a segmenter's stray blob can stretch a box
    in a few), the object's box overlaps the static's box across at
    least half of the narrower one and its bottom row lies inside the static's box (below
    its top edge by a tenth of its height, above its bottom edge): behind the box, the
    object would be cut at the static's top edge (:func:`cut_by_static`); in front of it,
    its bottom would be lower than the static's. A static box cut by the image's bottom
    border shows no height of the static (it only reaches out of the view): there the
    object's box height stands in for it. Whether it is really on top is for the
    physics to decide (see :func:`warpskill.optimize`); when the evidence is absent,
    nothing is returned.

    Args:
        masks: (N, 2 + K, h, w) masks in [0, 1]: hand, object, statics.
        contact: (N,) bool.
        min_frames: fewer frames after the release than this are ignored.
    """
    return _after_release(masks, contact, min_frames,
                          lambda obj, static, height: obj[:, 3] > static[:, 1] + 0.1 * height, share=0.8)


def cut_by_static(masks: np.ndarray, contact: np.ndarray, *, min_frames: int = 2) -> np.ndarray:
    """(N,) bool: frames after the release in which the object is cut by the first static box's top edge.

    As :func:`rests_on_static`, but the object's bottom row lies at the static box's top
    edge (from a quarter of the static's height above it to a tenth below it): the static box
    hides the object's lower part, so the object stands behind it, not on it (on top, its
    bottom would show inside the static's box).
    """
    return _after_release(masks, contact, min_frames, _at_top_edge, share=0.8)


def covers_static_top(masks: np.ndarray, contact: np.ndarray, *, min_frames: int = 2) -> np.ndarray:
    """(N,) bool: the frames of :func:`cut_by_static` in which the object's box also spans the
    static box across (to a tenth of the static's width on each side).

    On a static box narrower than itself an object covers the box's top edge, and its box
    meets the static's as that of an object behind the box does; on a wider one the top
    edge would show beside it, above its bottom. So here, and only here, the object may
    stand on the box as well as behind it: the physics tells them apart.
    """
    def rule(obj: np.ndarray, static: np.ndarray, height: np.ndarray) -> np.ndarray:
        margin = 0.1 * (static[:, 2] - static[:, 0])
        spans = (obj[:, 0] <= static[:, 0] + margin) & (obj[:, 2] >= static[:, 2] - margin)
        return _at_top_edge(obj, static, height) & spans

    return _after_release(masks, contact, min_frames, rule, share=0.8)


TOP_FACE_SHARE = 0.4
"""The upper share of an upright box's image box that its top face may fill: the complement of
the first guess's front face (:data:`~warpskill.optimizer.guess.FRONT_FACE_SHARE`)."""


def below_static_top_face(masks: np.ndarray, contact: np.ndarray, *, min_frames: int = 2) -> np.ndarray:
    """(N,) bool: frames after the release in which the object's bottom row lies deeper in the
    first static box than its top face reaches (more than :data:`TOP_FACE_SHARE` of its height
    below its top edge) and its box lies within the static's columns (to a tenth of the
    object's width on each side), in at least 80 % of them.

    An object behind a box shows its bottom only above the box's outline, whose top edge dips
    below the box's top row at most across the top face (a turned box's far edge); deeper and
    within the box's columns, the bottom is on the box or in front of it, never behind it. A
    wider object shows its bottom beside the box.
    """
    def rule(obj: np.ndarray, static: np.ndarray, height: np.ndarray) -> np.ndarray:
        margin = 0.1 * (obj[:, 2] - obj[:, 0])
        within = (obj[:, 0] >= static[:, 0] - margin) & (obj[:, 2] <= static[:, 2] + margin)
        return within & (obj[:, 3] > static[:, 1] + TOP_FACE_SHARE * height)

    return _after_release(masks, contact, min_frames, rule, share=0.8)


def _at_top_edge(obj: np.ndarray, static: np.ndarray, height: np.ndarray) -> np.ndarray:
    """Whether the object's boxes (n, 4) have their bottom row at the static's boxes' top edge:
    from a quarter of the static's height ``height`` (n,) [px] above it to a tenth below it."""
    return (obj[:, 3] >= static[:, 1] - 0.25 * height) & (obj[:, 3] <= static[:, 1] + 0.1 * height)


def _after_release(masks: np.ndarray, contact: np.ndarray, min_frames: int, rule, share: float) -> np.ndarray:
    """The frames from the release to the end, if in at least ``share`` of them the object's
    box overlaps the static's across half the narrower one, its bottom lies above the
    static's, and ``rule(object boxes, static boxes, static height)`` holds (boxes (n, 4),
    heights (n,) [px]: the static's box height, or the object's where the static's box
    reaches the bottom border)."""
    N = len(contact)
    out = np.zeros(N, dtype=bool)
    on = np.flatnonzero(contact)
    if masks.shape[1] < 3 or len(on) == 0 or on[-1] > N - 1 - min_frames:
        return out
    after = np.arange(on[-1] + 1, N)
    obj, static = _boxes(masks[after, 1] > 0.5), _boxes(masks[after, 2] > 0.5)
    if np.isnan(obj).any() or np.isnan(static).any():
        return out
    overlap = np.minimum(obj[:, 2], static[:, 2]) - np.maximum(obj[:, 0], static[:, 0])
    narrower = np.minimum(obj[:, 2] - obj[:, 0], static[:, 2] - static[:, 0])
    h = masks.shape[-2]
    height = np.where(static[:, 3] >= h - 1, obj[:, 3] - obj[:, 1], static[:, 3] - static[:, 1])
    placed = (overlap >= 0.5 * narrower) & rule(obj, static, height) & (obj[:, 3] < static[:, 3])
    if placed.mean() >= share:
        out[after] = True
    return out
