"""The outline proposed from the video itself: the object the hand takes and, for an action
with a static object, the object it is set onto, beside, behind or in front of.

The footage path follows an outline drawn on one frame (the polygon file of
``docs/formats.md``). :func:`propose_outline` draws that outline from the clip, with OpenCV
and MediaPipe's hand model only:

1. **The hands** are found in every frame (:func:`.hand_landmarks.find_hands`, and a hand it
   misses by colour and motion, :func:`.hand_regions.hand_regions`); one hand per frame is
   chosen (:func:`.hands.choose_hand`). Its grip is the fingertips' centre.
2. **The outlined frame** is where the hand is at the object: the frame whose grip moves
   least (camera shake included), among the frames the hand's landmarks are seen in (else
   those a hand region is); for an action with a static object among the later half of
   them, the release, where the object rests beside the static object.
3. **The object** is cut out by GrabCut seeded at the grip: surely the object just past the
   fingertips, probably the object within its size of the grip, surely not the hands; the
   size is the object noun's typical size measured with the hand as a ruler (a palm is
   :data:`~warpskill.nouns.typical.HAND_BREADTH` broad), or :data:`DEFAULT_OBJECT_EDGES`.
   The piece that holds the seed is the object. An object the hand does not carry (pressed,
   poked) and that is not put anywhere is cut out again at that seed, and outlined, on the
   nearest frame before the touch (else after it) where no hand hides it
   (:mod:`.unhidden_proposal`).
   At a release, what was there before the hand brought the object (the static object it
   touches, cut out with it) is taken off it (:mod:`.release_proposal`).
4. **The static object** (:func:`warpskill.contract.actions.has_static_object`) is cut out
   the same way, seeded beside the object on the side the action names (below it for
   ``put_onto`` and ``put_behind``, above it for ``put_in_front_of``, away from the arm for
   ``put_next_to``), the object and the hands surely not it.

Where the clip does not say what to outline (no hand in any frame, a hand seen too briefly,
two hands apart, nothing told apart at the grip, the static side out of view), :class:`OutlineUnsure` carries the
one line saying what to outline and a picture of what was seen.
"""

from __future__ import annotations

import dataclasses
import json
import os

import cv2
import numpy as np

from warpskill.contract.actions import has_static_object
from warpskill.contract.demonstration import DemonstrationError
from warpskill.contract.vocabulary import OBJECT, static_role
from warpskill.data.footage.hand_landmarks import (
    FINGERTIPS,
    INDEX_KNUCKLE,
    PINKY_KNUCKLE,
    WRIST,
    HandTracks,
    check_frames,
    find_hands,
    hand_size,
    hull_mask,
)
from warpskill.data.footage.hand_regions import hand_regions
from warpskill.data.footage.hands import choose_hand, hand_masks
from warpskill.data.footage.release_proposal import earlier_elsewhere, stayed
from warpskill.data.footage.unhidden_proposal import unhidden_view
from warpskill.data.readers.polygons import polygon_mask
from warpskill.media import HAND_COLOR, OBJECT_COLOR, STATIC_COLOR
from warpskill.nouns.typical import HAND_BREADTH, typical_size

DEFAULT_OBJECT_EDGES = (0.07, 0.15)
"""[m] middle and longest edge taken for an object without a noun: a hand-held everyday
object (a phone, a cup, a book are 7-15 cm across)."""

DEFAULT_STATIC_EDGES = (0.2, 0.3)
"""[m] middle and longest edge taken for a static object without a noun: a box, a tray, a
shelf's board, larger than what is set on it."""

SEED_HAND_SIZES = (0.3, 1.5)
"""Least and most radius of the probable object around its seed, in hand sizes: a small
object still gets a disc a finger wide, a large one no more than the reach of the grip."""

SURE_HAND_SIZE = 0.15
"""Radius of the sure object (or static object) at its seed, in hand sizes (a fingertip)."""

REGION_SEED_HAND_SIZES = 0.5
"""How far from the grip of a hand found only by colour and motion the seeds ahead of it and
to its sides lie, in hand sizes: such a region may leave out a fringe of skin at its tip,
which a seed just past the grip cuts out as the object (a third of a hand size was not
always past it on the rendered clips)."""

REGION_SEED_TURNS = (-np.pi / 2, 0.0, np.pi / 2)
"""Directions [rad] of those seeds from the region's centre-to-grip direction: ahead, and to
both sides (the region's farthest point is where the arm points, not where the fingers
touch: on the rendered clips the object lay beside it as often as ahead)."""

SEARCH_EDGES = 1.5
"""Half the side of the square GrabCut looks in, in longest edges of the expected object
(at least one hand size): what lies farther from the seed is surely background."""

TIGHT_HAND_FRACTION = 0.1
"""Half a finger's thickness as a fraction of the hand's size: the chosen hand's landmarks'
hull widened this much is surely not the object (the looser hand mask of
:func:`.hands.hand_masks` would swallow a small object under the fingers)."""

MIN_OBJECT_HAND_AREA = 0.03
"""Smallest object, its area in squared hand sizes (a 1.5 cm button against an 8.5 cm palm):
less is nothing told apart."""

MAX_OBJECT_SHARE = 0.6
"""Largest object, as a share of the frame: more is the background taken for the object."""

MIN_HAND_SECONDS = 0.5
"""Least time [s] the hand must be seen for the clip to show what it takes: a hand seen for a
few frames (passing by, cut by the view's edge) shows too little of it to tell."""

APART_HAND_SIZES = 3.0
"""Two hands whose grips are farther apart than this many hand sizes on the outlined frame
could each hold the object (two hands holding one object grip it closer together)."""

CARRIED_HAND_SIZES = 0.5
"""Least shift of the grip from the key frame's, in hand sizes, for a frame to tell a carried
piece from one left in place (less, and both look alike)."""

CARRIED_FRAMES = 6
"""Most frames on each side of the key frame a piece's motion is judged on (half a second
at 12 fps: before the hand has turned the object much)."""

CARRIED_SCORE = 0.2
"""Least :func:`_carried` score of a piece moving with the hand; where none has it, the piece
standing out most is taken (a pressed or poked object does not move with the hand)."""

THUMB_BASE, THUMB_TIP, INDEX_TIP = 2, 4, 8
"""Indices of the thumb's knuckle (MCP joint) and tip and of the index fingertip among
MediaPipe's 21 hand landmarks."""

GRABCUT_ROUNDS = 5
"""GrabCut's iterations (its colour models settle within a few)."""

GRABCUT_SEED = 0
"""OpenCV's random seed set before each GrabCut: the same frame gives the same piece whatever
ran before it in the process."""

POLYGON_TOLERANCE_PX = 0.75
"""Largest distance [px] of a proposed polygon from the traced mask's border."""


class OutlineUnsure(DemonstrationError):
    """The clip does not say what to outline.

    Attributes:
        line: one line: what was seen and what to outline.
        frame: the frame shown.
        picture: (H, W, 3) uint8 RGB, that frame with what was seen drawn on it.
    """

    def __init__(self, line: str, frame: int, picture: np.ndarray):
        super().__init__(line)
        self.line, self.frame, self.picture = line, frame, picture


@dataclasses.dataclass(frozen=True)
class OutlineProposal:
    """An outline proposed on one frame of a clip.

    Attributes:
        frame: the frame the polygons are on (0-based).
        polygons: label (``object``, ``static_0``, ...) -> (K, 2) float polygon (x, y) [px,
            continuous, (0, 0) the image's top-left corner].
        nouns: label -> noun, for the labels a noun was given for.
        image_size: (H, W) of the frames [px].
        tracks: the clip's hands (:func:`find_hands`), so the footage path does not find them again.
        regions: (N, H, W) bool, the hands found by colour and motion where no landmarks are
            (:func:`hand_regions`).
        seeds: label -> (x, y) [px], where each cut-out was seeded.
    """

    frame: int
    polygons: dict[str, np.ndarray]
    nouns: dict[str, str]
    image_size: tuple[int, int]
    tracks: HandTracks
    regions: np.ndarray
    seeds: dict[str, tuple[float, float]]

    def masks(self) -> dict[str, np.ndarray]:
        """Label -> (H, W) bool: the polygons filled as the polygon file is read."""
        return {label: polygon_mask(points, self.image_size) for label, points in self.polygons.items()}


def propose_outline(frames: np.ndarray, action: str, *, fps: float, object_noun: str | None = None,
                    static_noun: str | None = None) -> OutlineProposal:
    """The object the hand takes and the static objects, outlined on one frame of a clip (see
    the module docstring).

    Args:
        frames: (N, H, W, 3) uint8 RGB frames, in time order.
        action: the action shown (:data:`warpskill.ACTIONS`); a ``put_*`` action has a static object.
        fps: the frame rate [1/s] (the grip's speed is measured per second).
        object_noun, static_noun: what the object and the static object are (their typical
            sizes bound the cut-outs); None for a default size.

    Returns:
        The proposal.

    Raises:
        OutlineUnsure: the clip does not say what to outline (its line says what to outline).
        DemonstrationError: an unknown action, or a static noun for an action without a static object.
        ImportError: MediaPipe is not installed (the ``video`` extra).
    """
    frames = check_frames(frames)
    try:
        static = has_static_object(action)
    except ValueError as error:
        raise DemonstrationError(f"action: {error}") from None
    if static_noun is not None and not static:
        raise DemonstrationError(f"static_noun: {action} has no static object")
    h, w = frames.shape[1:3]
    what = "the object" + (" and the static object" if static else "")
    tracks = find_hands(frames)
    regions = hand_regions(frames, tracks)
    landmarks = choose_hand(tracks)
    grips, sizes = _grips(landmarks, regions)
    seen = np.flatnonzero(np.isfinite(grips[:, 0]))
    _check_hand_seen(frames, seen, grips, tracks, regions, fps, what)
    marked = np.flatnonzero(np.isfinite(landmarks).all(axis=(1, 2)))
    key = _key_frame(grips, sizes, marked if len(marked) else seen, fps, later_half=static)
    grip, size = grips[key], float(sizes[key])
    hands = _every_hand(tracks, regions, key, but=landmarks[key]) | _tight_hand(landmarks[key], regions[key], (h, w))
    _check_one_grip(tracks, key, frames[key], hands, what)
    edges = _edges_px(object_noun, DEFAULT_OBJECT_EDGES, size)
    seeds = _object_seeds(landmarks[key], regions[key], grip, size)
    cut = [(seed, _cut_out(frames[key], seed, size, edges, hands)) for seed in seeds]
    pieces = [(seed, piece) for seed, piece in cut if _plausible(piece, size)]
    if not pieces:
        raise OutlineUnsure(f"frame {key}: nothing told apart at the hand's fingertips: outline {what} on one frame "
                            f"(--polygons)", key, _picture(frames[key], {}, hands, grip))
    seed, obj, carried = _the_object(frames, key, pieces, grips, sizes, tracks, regions, hands)
    if not carried and not static:  # a put's object was carried to where it is released
        key, seed, obj, hands = _unhidden(frames, key, (seed, obj, hands), size, edges, tracks, regions)
    if static:
        obj = _brought(frames, key, obj, grips, size, tracks, regions)
    masks, seeds, nouns = {OBJECT: obj}, {OBJECT: seed}, {OBJECT: object_noun} if object_noun else {}
    if static:
        label = static_role(0)
        seeds[label], masks[label] = _static_object(frames[key], key, action, obj, landmarks[key], size, static_noun,
                                                    hands)
        nouns.update({label: static_noun} if static_noun else {})
    polygons = {label: _polygon(mask) for label, mask in masks.items()}
    seeds = {label: (float(x), float(y)) for label, (x, y) in seeds.items()}
    return OutlineProposal(key, polygons, nouns, (h, w), tracks, regions, seeds)


def write_outline(proposal: OutlineProposal, path: str | os.PathLike) -> None:
    """Write the proposal as the polygon file ``--polygons`` reads (``docs/formats.md``):
    ``frame``, ``object``, ``static`` and, when known, ``object_noun``."""
    statics = sorted((label for label in proposal.polygons if label != OBJECT),
                     key=lambda label: int(label.rsplit("_", 1)[1]))
    data = {"frame": int(proposal.frame), "object": _rounded(proposal.polygons[OBJECT]),
            "static": [_rounded(proposal.polygons[label]) for label in statics]}
    if OBJECT in proposal.nouns:
        data["object_noun"] = proposal.nouns[OBJECT]
    with open(path, "w") as handle:
        json.dump(data, handle)
        handle.write("\n")


def proposal_picture(frame: np.ndarray, proposal: OutlineProposal) -> np.ndarray:
    """(H, W, 3) uint8 RGB: the outlined frame ``frame`` with the proposal's polygons and seeds drawn."""
    masks = proposal.masks()
    return _picture(frame, masks, None, None, seeds=proposal.seeds)


_SIDES = {"put_onto": "below", "put_behind": "in front of", "put_in_front_of": "behind", "put_next_to": "beside"}
"""Where the static object lies from the object, in words, per action with a static object."""


def _grips(landmarks: np.ndarray, regions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) the chosen hand's grip [px] (its fingertips' centre; for a colour-and-motion
    region, its point farthest from where it enters the image: the arm comes from outside)
    and (N,) its size [px] (a region's: the landmark hands' median, else half the square root
    of its area); NaN where no hand is seen."""
    n = len(landmarks)
    grips = landmarks[:, list(FINGERTIPS)].mean(axis=1)
    sizes = hand_size(landmarks)
    known = np.isfinite(sizes)
    typical = float(np.median(sizes[known])) if known.any() else np.nan
    for k in np.flatnonzero(~known & regions.reshape(n, -1).any(axis=1)):
        region = regions[k]
        entry = np.zeros_like(region)
        entry[[0, -1], :], entry[:, [0, -1]] = region[[0, -1], :], region[:, [0, -1]]
        if not entry.any():
            continue
        reach = cv2.distanceTransform((~entry).astype(np.uint8), cv2.DIST_L2, 3)
        y, x = np.unravel_index(np.argmax(np.where(region, reach, -1.0)), region.shape)
        grips[k] = (x + 0.5, y + 0.5)
        sizes[k] = typical if np.isfinite(typical) else 0.5 * np.sqrt(region.sum())
    return grips, sizes


def _check_hand_seen(frames: np.ndarray, seen: np.ndarray, grips: np.ndarray, tracks: HandTracks,
                     regions: np.ndarray, fps: float, what: str) -> None:
    """OutlineUnsure where the hand is ``seen`` in no frame, or in fewer than
    :data:`MIN_HAND_SECONDS` of them; ``what`` names what to outline."""
    n = len(frames)
    if not len(seen):
        raise OutlineUnsure(f"no hand in any of the {n} frames: outline {what} on one frame (--polygons)",
                            n // 2, _picture(frames[n // 2], {}, None, None))
    if len(seen) < MIN_HAND_SECONDS * fps:
        k = int(seen[len(seen) // 2])
        raise OutlineUnsure(f"a hand in only {len(seen)} of the {n} frames ({len(seen) / fps:.2g} s), too briefly to "
                            f"see what it takes: outline {what} on one frame (--polygons)",
                            k, _picture(frames[k], {}, _every_hand(tracks, regions, k), grips[k]))


def _key_frame(grips: np.ndarray, sizes: np.ndarray, seen: np.ndarray, fps: float, *, later_half: bool) -> int:
    """The frame the hand is at the object: its grip's slowest frame [hand sizes per second]
    among the ``seen`` frames (the later half of them for a release), the earliest on ties."""
    candidates = seen[len(seen) // 2 :] if later_half else seen
    speed = np.full(len(grips), np.inf)
    for k in candidates:
        steps = [np.linalg.norm(grips[j] - grips[k]) * fps / abs(j - k) for j in (k - 1, k + 1)
                 if 0 <= j < len(grips) and np.isfinite(grips[j, 0])]
        speed[k] = np.mean(steps) / sizes[k] if steps else np.inf
    if not np.isfinite(speed[candidates]).any():
        return int(candidates[len(candidates) // 2])
    return int(candidates[np.argmin(speed[candidates])])


def _every_hand(tracks: HandTracks, regions: np.ndarray, k: int, *, but: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: every hand seen in frame ``k``, forearms included; ``but`` (21, 2) [px]:
    the landmarks of a hand left out."""
    out = regions[k].copy()
    for landmarks in tracks.all_landmarks():
        if but is None or not np.array_equal(landmarks[k], but, equal_nan=True):
            out |= hand_masks(landmarks[k : k + 1], tracks.image_size, forearm=True)[0]
    return out


def _tight_hand(points: np.ndarray, region: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: the chosen hand drawn tight (its landmarks' hull widened by
    :data:`TIGHT_HAND_FRACTION` of its size, the forearm) or its region."""
    if not np.isfinite(points).all():
        return region.copy()
    loose = hand_masks(points[None], image_size, forearm=True)[0]
    hand = hand_masks(points[None], image_size, forearm=False)[0]
    return (loose & ~hand) | hull_mask(points, image_size, TIGHT_HAND_FRACTION * float(hand_size(points)))


def _check_one_grip(tracks: HandTracks, key: int, frame: np.ndarray, hands: np.ndarray, what: str) -> None:
    """OutlineUnsure where two hands are seen in frame ``key`` with grips farther apart than
    :data:`APART_HAND_SIZES` hand sizes: either could hold the object."""
    present = np.flatnonzero(tracks.present()[key])
    if len(present) < 2:
        return
    points = tracks.landmarks[key, present]
    grips = points[:, list(FINGERTIPS)].mean(axis=1)
    if np.linalg.norm(grips[0] - grips[1]) > APART_HAND_SIZES * float(np.max(hand_size(points))):
        picture = _picture(frame, {}, hands, None, seeds={"grip": tuple(grips[0]), "other grip": tuple(grips[1])})
        raise OutlineUnsure(f"frame {key}: two hands apart, either could hold the object: outline {what} on one frame "
                            f"(--polygons)", key, picture)


def _edges_px(noun: str | None, default: tuple[float, float], size: float) -> tuple[float, float]:
    """The middle and longest edge [px] of an object of ``noun`` (``default`` [m] without a
    known one), measured with the hand of ``size`` [px] as a ruler."""
    typical = typical_size(noun)
    middle, longest = default if typical is None else typical.edges[1:]
    return middle * size / HAND_BREADTH, longest * size / HAND_BREADTH


def _object_seeds(points: np.ndarray, region: np.ndarray, grip: np.ndarray, size: float) -> list[np.ndarray]:
    """(2,) [px] seeds where the object may be: past the fingertips (what the fingers press),
    past the index fingertip (what it pokes), past the index and the little finger's knuckles
    and past the thumb (what the fist holds sticks out at its sides); for a hand found only
    as a ``region`` (H, W), just past its grip away from the region's centre,
    :data:`REGION_SEED_HAND_SIZES` from it ahead and to both sides (:data:`REGION_SEED_TURNS`),
    and at its grip."""

    def past(point: np.ndarray, origin: np.ndarray, reach: float = SURE_HAND_SIZE, turn: float = 0.0) -> np.ndarray:
        away = point - origin
        norm = float(np.linalg.norm(away))
        cos, sin = np.cos(turn), np.sin(turn)
        return point if norm < 1e-6 else point + np.array([[cos, -sin], [sin, cos]]) @ away / norm * reach * size

    if not np.isfinite(points).all():
        ys, xs = np.nonzero(region)
        centre = np.array([xs.mean() + 0.5, ys.mean() + 0.5])
        return [past(grip, centre), *(past(grip, centre, REGION_SEED_HAND_SIZES, turn) for turn in REGION_SEED_TURNS),
                grip]

    return [past(grip, points[WRIST]), past(points[INDEX_TIP], points[INDEX_KNUCKLE]),
            past(points[INDEX_KNUCKLE], points[PINKY_KNUCKLE]), past(points[PINKY_KNUCKLE], points[INDEX_KNUCKLE]),
            past(points[THUMB_TIP], points[THUMB_BASE])]


def _plausible(piece: np.ndarray, size: float) -> bool:
    """Whether a cut-out piece may be an object: at least :data:`MIN_OBJECT_HAND_AREA` squared
    hand sizes of ``size`` [px], at most :data:`MAX_OBJECT_SHARE` of the frame."""
    return bool(piece.sum() >= MIN_OBJECT_HAND_AREA * size**2 and piece.mean() <= MAX_OBJECT_SHARE)


def _carried(frames: np.ndarray, key: int, piece: np.ndarray, grips: np.ndarray, sizes: np.ndarray,
             tracks: HandTracks, regions: np.ndarray) -> float:
    """How much ``piece`` (H, W) of frame ``key`` moves with the hand rather than staying, in
    [-1, 1]: over the frames whose grip lies :data:`CARRIED_HAND_SIZES` or more from the key
    frame's (at most :data:`CARRIED_FRAMES` on each side), the piece's colour difference when
    left in place against when shifted with the grip, (stay - carried) / (stay + carried); the
    better side's median (a hand takes the object after the key frame, or brought it there);
    0 where the hand never moves that far."""
    h, w = piece.shape
    ys, xs = np.nonzero(piece)
    reference = frames[key][ys, xs].astype(np.float32)
    sides = []
    for step in (1, -1):
        scores = []
        j = key + step
        while 0 <= j < len(frames) and len(scores) < CARRIED_FRAMES:
            shift = grips[j] - grips[key]
            if np.isfinite(shift).all() and np.linalg.norm(shift) >= CARRIED_HAND_SIZES * sizes[key]:
                hand = _every_hand(tracks, regions, j)
                stay = _difference(frames[j], hand, xs, ys, reference)
                carried_xs, carried_ys = np.round(xs + shift[0]).astype(int), np.round(ys + shift[1]).astype(int)
                moved = _difference(frames[j], hand, carried_xs, carried_ys, reference)
                if np.isfinite(stay) and np.isfinite(moved) and stay + moved > 0:
                    scores.append((stay - moved) / (stay + moved))
            j += step
        if scores:
            sides.append(float(np.median(scores)))
    return max(sides, default=0.0)


def _contrast(frame: np.ndarray, piece: np.ndarray, hands: np.ndarray, size: float) -> float:
    """How much ``piece`` (H, W) stands out from what surrounds it (a ring
    :data:`SURE_HAND_SIZE` hand sizes wide, off the hands): the distance [CIELAB, 8-bit] of
    their mean colours. A piece cut out of a uniform surface hardly does."""
    width = max(3, 2 * int(round(SURE_HAND_SIZE * size)) + 1)
    ring = cv2.dilate(piece.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (width, width))).astype(bool)
    ring &= ~piece & ~hands
    if not ring.any():
        return 0.0
    lab = cv2.cvtColor(frame, cv2.COLOR_RGB2LAB).astype(np.float32)
    return float(np.linalg.norm(lab[piece].mean(axis=0) - lab[ring].mean(axis=0)))


def _the_object(frames: np.ndarray, key: int, pieces: list, grips: np.ndarray, sizes: np.ndarray,
                tracks: HandTracks, regions: np.ndarray, hands: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The object among the ``pieces`` ((seed, (H, W) bool) cut out at the key frame): those
    moving with the hand (:func:`_carried` above :data:`CARRIED_SCORE`), else the one standing
    out most from its surroundings (:func:`_contrast`); with the pieces alike them
    (:func:`_alike`) and the part hidden by the hand (:func:`_under_hand`).

    Returns:
        The first chosen piece's seed (x, y) [px], the object's (H, W) bool mask, and whether
        it moves with the hand.
    """
    size = float(sizes[key])
    carried = np.array([_carried(frames, key, piece, grips, sizes, tracks, regions) for _, piece in pieces])
    if (carried > CARRIED_SCORE).any():
        chosen = list(np.flatnonzero(carried > CARRIED_SCORE))
    else:
        chosen = [int(np.argmax([_contrast(frames[key], piece, hands, size) for _, piece in pieces]))]
    alike = _alike(frames[key], [piece for _, piece in pieces], chosen, hands, size)
    return pieces[chosen[0]][0], _under_hand(alike, hands, grips[key]), bool((carried > CARRIED_SCORE).any())


def _unhidden(frames: np.ndarray, key: int, touched: tuple, size: float, edges: tuple[float, float],
              tracks: HandTracks, regions: np.ndarray) -> tuple:
    """An object the hand does not carry, cut out again at its seed where no hand hides it
    (:func:`.unhidden_proposal.unhidden_view`: no hand within the object's longest edge of
    the seed carried there, nor within the most its cut-out reaches, :data:`SEED_HAND_SIZES`).

    Args:
        touched: the seed (x, y) [px], the (H, W) bool object and the hands at frame ``key``,
            kept where no frame serves or nothing is told apart there.

    Returns:
        The frame, the seed, the object's (H, W) bool mask and the hands there.
    """
    view = unhidden_view(frames, key, np.array([touched[0]]), lambda j: _every_hand(tracks, regions, j),
                         max(edges[1], SEED_HAND_SIZES[1] * size))
    if view is None:
        return (key, *touched)
    j, (seed,) = view
    hands = _every_hand(tracks, regions, j)
    piece = _cut_out(frames[j], seed, size, edges, hands)
    return (j, seed, piece, hands) if _plausible(piece, size) else (key, *touched)


def _brought(frames: np.ndarray, key: int, obj: np.ndarray, grips: np.ndarray, size: float, tracks: HandTracks,
             regions: np.ndarray) -> np.ndarray:
    """(H, W) bool: the object ``obj`` released at frame ``key`` less what was there before the
    hand brought it (:mod:`.release_proposal`: the static object it touches, cut out with it),
    its largest piece with holes filled; ``obj`` where that is not told, or leaves no
    :func:`_plausible` piece."""
    ys, xs = np.nonzero(obj)
    earlier = earlier_elsewhere(grips, key, float(max(np.ptp(xs), np.ptp(ys)) + 1))
    before = None if earlier is None else stayed(frames, key, earlier, lambda j: _every_hand(tracks, regions, j))
    if before is None:
        return obj
    rest = cv2.morphologyEx((obj & ~before).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(rest, connectivity=8)
    if count < 2:
        return obj
    piece = _filled(labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA])))
    return piece if _plausible(piece, size) else obj


def _static_object(frame: np.ndarray, key: int, action: str, obj: np.ndarray, points: np.ndarray, size: float,
                   noun: str | None, hands: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The static object of ``action`` beside the object ``obj`` (H, W) in ``frame`` (the key
    frame ``key``): its seed (x, y) [px] (:func:`_static_seed`, ``points`` the hand's (21, 2)
    landmarks) and (H, W) bool mask (:func:`_static_piece`, bounded by ``noun``'s size).

    Raises:
        OutlineUnsure: nothing plausible is cut out there.
    """
    seed = _static_seed(action, obj, points, _edges_px(noun, DEFAULT_STATIC_EDGES, size), size)
    piece = _static_piece(frame, seed, size, noun, hands | obj)
    if not _plausible(piece, size):
        raise OutlineUnsure(f"frame {key}: no static object told apart {_SIDES[action]} the object: outline it "
                            f"(--polygons)", key, _picture(frame, {OBJECT: obj, "static": piece}, hands, seed))
    return seed, piece


def _static_piece(frame: np.ndarray, seed: np.ndarray, size: float, noun: str | None, not_it: np.ndarray) -> np.ndarray:
    """(H, W) bool: the static object cut out at ``seed`` (x, y) [px] (empty when the seed
    lies outside the image), bounded by its noun's typical size."""
    if not _inside(seed, not_it.shape):
        return np.zeros(not_it.shape, dtype=bool)
    return _cut_out(frame, seed, size, _edges_px(noun, DEFAULT_STATIC_EDGES, size), not_it)


def _alike(frame: np.ndarray, pieces: list[np.ndarray], chosen, hands: np.ndarray, size: float) -> np.ndarray:
    """(H, W) bool: the ``chosen`` pieces and every other piece more like them than they are
    like their surroundings (its mean colour nearer to theirs than half their
    :func:`_contrast`): one object seen on both sides of the hand holding it."""
    union = np.any([pieces[k] for k in chosen], axis=0)
    lab = cv2.cvtColor(frame, cv2.COLOR_RGB2LAB).astype(np.float32)
    colour, contrast = lab[union].mean(axis=0), _contrast(frame, union, hands, size)
    for k, piece in enumerate(pieces):
        if k not in chosen and np.linalg.norm(lab[piece].mean(axis=0) - colour) < 0.5 * contrast:
            union = union | piece
    return union


def _under_hand(obj: np.ndarray, hands: np.ndarray, grip: np.ndarray) -> np.ndarray:
    """(H, W) bool: the object ``obj`` with its part hidden by the hand (the hands' pixels
    within the convex hull of the object and the grip), its largest piece."""
    ys, xs = np.nonzero(obj)
    points = np.concatenate([np.stack([xs, ys], axis=1), np.round(grip - 0.5)[None]]).astype(np.int32)
    hull = np.zeros(obj.shape, dtype=np.uint8)
    cv2.fillConvexPoly(hull, cv2.convexHull(points), 1)
    whole = (obj | (hull.astype(bool) & hands)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(whole, connectivity=8)
    return labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))


def _difference(frame: np.ndarray, hand: np.ndarray, xs: np.ndarray, ys: np.ndarray, reference: np.ndarray) -> float:
    """Mean absolute colour difference [8-bit levels] between ``reference`` (K, 3) and ``frame``
    at pixels (``xs``, ``ys``) inside the image and off ``hand``; NaN where fewer than half are."""
    h, w = hand.shape
    ok = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
    ok[ok] &= ~hand[ys[ok], xs[ok]]
    if ok.mean() < 0.5:
        return float("nan")
    return float(np.abs(frame[ys[ok], xs[ok]].astype(np.float32) - reference[ok]).mean())


def _static_seed(action: str, obj: np.ndarray, points: np.ndarray, edges: tuple[float, float],
                 size: float) -> np.ndarray:
    """(2,) [px] the static object's seed: half its middle edge past the object's box on the
    action's side (:data:`_SIDES`; beside: away from the arm)."""
    ys, xs = np.nonzero(obj)
    x0, x1, y0, y1 = xs.min(), xs.max() + 1.0, ys.min(), ys.max() + 1.0
    gap = float(np.clip(0.5 * edges[0], SEED_HAND_SIZES[0] * size, SEED_HAND_SIZES[1] * size))
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    if action in ("put_onto", "put_behind"):
        return np.array([centre[0], y1 + gap])
    if action == "put_in_front_of":
        return np.array([centre[0], y0 - gap])
    arm = centre[0] - points[WRIST, 0] if np.isfinite(points).all() else centre[0] - obj.shape[1] / 2
    return np.array([x1 + gap if arm >= 0 else x0 - gap, centre[1]])


def _inside(point: np.ndarray, image_size: tuple[int, int]) -> bool:
    """Whether ``point`` (x, y) [px] lies in the image."""
    return bool(0 <= point[0] < image_size[1] and 0 <= point[1] < image_size[0])


def _cut_out(frame: np.ndarray, seed: np.ndarray, size: float, edges: tuple[float, float],
             not_it: np.ndarray) -> np.ndarray:
    """(H, W) bool: GrabCut's piece of ``frame`` nearest to ``seed`` (x, y) [px]: surely what lies
    within :data:`SURE_HAND_SIZE` hand sizes of the seed's nearest pixel outside ``not_it`` (H,
    W), probably within half its middle edge, surely not farther than :data:`SEARCH_EDGES`
    longest edges nor in ``not_it``; empty when the probable disc is all ``not_it``."""
    h, w = not_it.shape
    yy, xx = np.mgrid[0:h, 0:w]
    distance = np.hypot(xx + 0.5 - seed[0], yy + 0.5 - seed[1])
    probable = float(np.clip(0.5 * edges[0], SEED_HAND_SIZES[0] * size, SEED_HAND_SIZES[1] * size))
    search = max(SEARCH_EDGES * edges[1], size)
    mask = np.full((h, w), cv2.GC_BGD, dtype=np.uint8)
    mask[(np.abs(xx + 0.5 - seed[0]) <= search) & (np.abs(yy + 0.5 - seed[1]) <= search)] = cv2.GC_PR_BGD
    free = np.where(not_it, np.inf, distance)
    nearest = float(free.min())
    if nearest > probable:
        return np.zeros((h, w), dtype=bool)
    mask[free <= probable] = cv2.GC_PR_FGD
    mask[free <= nearest + SURE_HAND_SIZE * size] = cv2.GC_FGD
    mask[not_it] = cv2.GC_BGD
    if not ((mask == cv2.GC_BGD) | (mask == cv2.GC_PR_BGD)).any():
        return np.zeros((h, w), dtype=bool)
    background, foreground = np.zeros((1, 65)), np.zeros((1, 65))
    cv2.setRNGSeed(GRABCUT_SEED)  # its colour models start from k-means on OpenCV's global generator
    cv2.grabCut(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR), mask, None, background, foreground, GRABCUT_ROUNDS,
                cv2.GC_INIT_WITH_MASK)
    piece = ((mask == cv2.GC_FGD) | (mask == cv2.GC_PR_FGD)).astype(np.uint8)
    piece = cv2.morphologyEx(piece, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))  # specks off, a cable kept
    count, labels = cv2.connectedComponents(piece, connectivity=8)
    if count < 2:
        return np.zeros((h, w), dtype=bool)
    free[labels == 0] = np.inf
    return _filled(labels == labels.flat[int(np.argmin(free))])


def _filled(mask: np.ndarray) -> np.ndarray:
    """(H, W) bool: ``mask`` with its holes filled."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = np.zeros(mask.shape, dtype=np.uint8)
    cv2.drawContours(out, contours, -1, 1, thickness=cv2.FILLED)
    return out.astype(bool)


def _polygon(mask: np.ndarray) -> np.ndarray:
    """(K, 2) float: the largest piece of ``mask`` traced as a polygon [px, continuous]."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contour = max(contours, key=cv2.contourArea)
    points = cv2.approxPolyDP(contour, POLYGON_TOLERANCE_PX, True).reshape(-1, 2).astype(float) + 0.5
    if len(points) < 3:  # a sliver: its box
        x, y, bw, bh = cv2.boundingRect(contour)
        points = np.array([[x, y], [x + bw, y], [x + bw, y + bh], [x, y + bh]], dtype=float)
    return points


def _rounded(points: np.ndarray) -> list[list[float]]:
    """A polygon as JSON lists, to 1/100 px."""
    return [[round(float(x), 2), round(float(y), 2)] for x, y in points]


def _picture(frame: np.ndarray, masks: dict[str, np.ndarray], hands: np.ndarray | None, seed: np.ndarray | None,
             *, seeds: dict[str, tuple[float, float]] | None = None) -> np.ndarray:
    """(H, W, 3) uint8 RGB: ``frame`` with the hands tinted, each mask outlined in its role's
    colour and the seeds marked."""
    out = frame.astype(np.float32)
    if hands is not None:
        out[hands] = 0.6 * out[hands] + 0.4 * np.array(HAND_COLOR, dtype=np.float32)
    out = out.astype(np.uint8)
    for label, mask in masks.items():
        contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(out, contours, -1, OBJECT_COLOR if label == OBJECT else STATIC_COLOR, 2)
    marks = list((seeds or {}).values()) + ([tuple(seed)] if seed is not None else [])
    for x, y in marks:
        cv2.drawMarker(out, (int(round(x)), int(round(y))), (255, 255, 0), cv2.MARKER_CROSS, 12, 2)
    return out
