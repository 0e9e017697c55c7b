"""The hand from landmarks (geometry, synthetic) and from real frames (MediaPipe, optional)."""

from __future__ import annotations

import sys
from pathlib import Path, PurePosixPath

import numpy as np
import pytest

from warpskill.data.footage import hand_landmarks, hand_regions
from warpskill.data.footage.hand_landmarks import HandTracks, find_hands, hand_model_path
from warpskill.data.footage.hands import choose_hand, hand_masks, hand_measurements

FOOTAGE = Path(__file__).resolve().parents[2] / "shared" / "data" / "real_footage"


def open_hand(wrist=(100.0, 150.0), direction=(0.0, -1.0), scale=1.0) -> np.ndarray:
    """(21, 2) landmarks [px] of a flat open hand, fingers pointing along ``direction``:
    palm 8.5 units broad and 10 long, fingers ~8 long, ``scale`` px per unit."""
    knuckles_x = np.array([-4.25, -1.4, 1.4, 4.25])  # index, middle, ring, little (x across the palm)
    points = [(0.0, 0.0)]  # wrist
    points += [(-3.5, 2.5), (-5.0, 4.5), (-6.0, 6.5), (-6.5, 8.5)]  # thumb
    for x in knuckles_x:
        points += [(x, 10.0), (x, 13.0), (x, 15.5), (x, 17.5)]
    local = np.array(points)  # y: along the fingers, x: across
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    across = np.array([-d[1], d[0]])
    return np.asarray(wrist, float) + scale * (local[:, :1] * across + local[:, 1:] * d)


SKIN_RGB = (224, 172, 140)
"""A light skin tone (Cr ~157, Cb ~103: inside Chai & Ngan's ranges)."""


def no_tracks(n: int, image_size=(120, 200)) -> HandTracks:
    """HandTracks of ``n`` frames without any hand."""
    return HandTracks(
        np.full((n, hand_landmarks.MAX_HANDS, 21, 2), np.nan),
        np.full((n, hand_landmarks.MAX_HANDS), np.nan),
        np.full((n, hand_landmarks.MAX_HANDS), "", dtype="<U5"),
        np.full((n, hand_landmarks.MAX_HANDS), -1),
        image_size,
    )


def grey_texture(shape, seed=0) -> np.ndarray:
    """(H, W, 3) uint8 grey blotches (no chroma, so never skin), corners for the camera's flow."""
    rng = np.random.default_rng(seed)
    coarse = rng.integers(50, 200, size=(shape[0] // 6 + 1, shape[1] // 6 + 1), dtype=np.uint8)
    grey = np.kron(coarse, np.ones((6, 6), dtype=np.uint8))[: shape[0], : shape[1]]
    return np.repeat(grey[..., None], 3, axis=-1)


def arm_clip(n=24, size=(120, 200)):
    """(n, H, W, 3) frames of an arm (a skin band 22 px wide) coming up from the bottom border
    over a grey background, reaching in from frame 6 on and sweeping sideways, and the
    (n, H, W) bool truth."""
    h, w = size
    frames = np.repeat(grey_texture(size)[None], n, axis=0)
    truth = np.zeros((n, h, w), dtype=bool)
    ys, xs = np.mgrid[:h, :w]
    for k in range(6, n):
        x = 40 + 6 * (k - 6)  # the arm's axis at the bottom border [px]
        top = h - min(70, 15 * (k - 4))  # its tip
        truth[k] = (np.abs(xs - x - 0.3 * (h - ys)) < 11) & (ys >= top)
        frames[k][truth[k]] = SKIN_RGB
    return frames, truth


def test_a_moving_arm_coming_in_from_the_border_is_found_where_mediapipe_saw_no_hand():
    from warpskill.data.boxes.overlap import box_ious, mask_box

    frames, truth = arm_clip()
    regions = hand_regions.hand_regions(frames, no_tracks(len(frames)))
    assert regions.shape == truth.shape
    assert not regions[:6].any()  # no arm yet, nothing found
    boxes = np.stack([mask_box(mask) for mask in truth[6:]])
    assert (box_ious(regions[6:], boxes) >= 0.7).all(), np.round(box_ious(regions[6:], boxes), 2)
    assert (regions & ~truth).sum() < 0.1 * regions.sum()  # the background is not taken


def test_frames_with_a_landmark_hand_get_no_region_and_the_clips_own_skin_is_learned():
    frames, truth = arm_clip()
    tracks = no_tracks(len(frames))
    # a hand detected on the arm's tip in frames 15 to 17
    for k in (15, 16, 17):
        ys, xs = np.nonzero(truth[k])
        top = ys.min()
        tip = np.array([xs[ys == top].mean(), top + 20.0])
        tracks.landmarks[k, 0] = tip + np.random.default_rng(k).uniform(-8, 8, size=(21, 2))
        tracks.followed[k, 0] = 0
    regions = hand_regions.hand_regions(frames, tracks)
    assert not regions[15:18].any()
    found = regions.any(axis=(1, 2))
    assert found[6:15].all() and found[18:].all() and not found[:6].any()
    assert (regions & ~truth).sum() < 0.1 * regions.sum()


def test_a_still_skin_coloured_thing_is_not_a_hand_even_when_the_camera_moves():
    # a skin-coloured cupboard at the bottom border of a hand-free clip, the camera panning
    n, h, w = 24, 120, 200
    scene = grey_texture((h, w + 3 * n), seed=1)
    scene[70:, 60:130] = SKIN_RGB
    frames = np.stack([scene[:, 3 * k : 3 * k + w] for k in range(n)])
    assert not hand_regions.hand_regions(frames, no_tracks(n)).any()
    # without compensating the camera's motion, the panning cupboard would be a moving skin blob
    moved = np.abs(frames[1:].astype(int) - frames[:-1]).max(axis=-1) > hand_regions.MOTION_THRESHOLD
    assert moved[:, 70:, 60:140].mean() > 0.05


def test_regions_refuse_frames_that_are_not_the_tracks():
    frames, _ = arm_clip(n=8)
    with pytest.raises(ValueError, match="tracks"):
        hand_regions.hand_regions(frames, no_tracks(7))
    with pytest.raises(ValueError, match=r"\(N, H, W, 3\) uint8"):
        hand_regions.hand_regions(frames[..., 0], no_tracks(8))


def tracks_of(*hand_sets: np.ndarray, image_size=(240, 320)) -> HandTracks:
    """HandTracks of one frame holding the given hands (detected)."""
    landmarks = np.full((1, hand_landmarks.MAX_HANDS, 21, 2), np.nan)
    scores = np.full((1, hand_landmarks.MAX_HANDS), np.nan)
    handedness = np.full((1, hand_landmarks.MAX_HANDS), "", dtype="<U5")
    followed = np.full((1, hand_landmarks.MAX_HANDS), -1)
    for k, points in enumerate(hand_sets):
        landmarks[0, k], scores[0, k], handedness[0, k], followed[0, k] = points, 0.9, "Left", 0
    return HandTracks(landmarks, scores, handedness, followed, image_size)


def test_mask_covers_the_landmarks_and_is_wider_than_their_hull():
    points = open_hand(scale=4.0)
    mask = hand_masks(points[None], (240, 320), forearm=False)[0]
    xy = np.round(points).astype(int)
    assert mask[xy[:, 1], xy[:, 0]].all()
    hull = hand_landmarks.hull_mask(points, (240, 320), 0.0)
    assert mask.sum() > 1.3 * hull.sum()
    assert (mask | hull).sum() == mask.sum()  # the hull is inside the mask
    # widened by a fraction of the palm's breadth (34 px here): not beyond about that
    breadth = hand_measurements(points[None])[0, 0]
    ys, xs = np.nonzero(mask)
    assert xs.max() - xs.min() < np.ptp(points[:, 0]) + 2 * hand_landmarks.WIDEN_FRACTION * breadth + 3
    assert xs.max() - xs.min() > np.ptp(points[:, 0]) + hand_landmarks.WIDEN_FRACTION * breadth


def test_forearm_reaches_the_border_when_the_hand_comes_in_from_it():
    # wrist near the bottom border, fingers pointing up (into the image)
    points = open_hand(wrist=(160.0, 225.0), direction=(0.0, -1.0), scale=4.0)
    with_arm = hand_masks(points[None], (240, 320), forearm=True)[0]
    without = hand_masks(points[None], (240, 320), forearm=False)[0]
    assert with_arm[-1, 150:170].all()  # the bottom row under the wrist
    assert not without[-1].any()
    assert (with_arm | without).sum() == with_arm.sum()


def test_forearm_is_a_stub_when_the_border_is_far():
    # a small hand in the middle of a large image, pointing right: the arm goes left
    points = open_hand(wrist=(500.0, 300.0), direction=(1.0, 0.0), scale=2.0)
    mask = hand_masks(points[None], (600, 1000), forearm=True)[0]
    length = hand_measurements(points[None])[0, 1]
    ys, xs = np.nonzero(mask)
    assert xs.min() > 0  # does not reach the left border
    assert 500 - xs.min() == pytest.approx(length, abs=0.25 * length)
    assert mask[300, 500 - int(0.8 * length)]  # the forearm's axis is in the mask


def test_no_landmarks_no_mask_and_no_measurements():
    landmarks = np.stack([open_hand(scale=4.0), np.full((21, 2), np.nan)])
    masks = hand_masks(landmarks, (240, 320))
    assert masks[0].any() and not masks[1].any()
    sizes = hand_measurements(landmarks)
    assert np.isnan(sizes[1]).all()
    assert sizes[0] == pytest.approx([8.5 * 4.0, (np.hypot(1.4, 10.0) + 7.5) * 4.0])


def test_bad_landmarks_shape_is_refused():
    with pytest.raises(ValueError, match="landmarks"):
        hand_masks(np.zeros((3, 20, 2)), (240, 320))
    with pytest.raises(ValueError, match="landmarks"):
        hand_measurements(np.zeros((21, 2)))


def test_choose_hand_keeps_the_hand_touching_the_object():
    left = open_hand(wrist=(60.0, 200.0), scale=3.0)
    right = open_hand(wrist=(250.0, 200.0), scale=3.0)
    tracks = tracks_of(left, right)
    tracks.scores[0] = [0.95, 0.6]  # the far hand is the more confident one
    obj = np.zeros((1, 240, 320), dtype=bool)
    obj[0, 120:160, 235:275] = True  # under the right hand's fingers
    assert np.array_equal(choose_hand(tracks, obj)[0], right)
    assert np.array_equal(choose_hand(tracks)[0], left)  # without the object: the higher score
    with pytest.raises(ValueError, match="object_masks"):
        choose_hand(tracks, obj[:, :100])


def test_bad_frames_are_refused_before_anything_else():
    with pytest.raises(ValueError, match=r"\(N, H, W, 3\) uint8"):
        find_hands(np.zeros((4, 24, 32), dtype=np.uint8))
    with pytest.raises(ValueError, match=r"\(N, H, W, 3\) uint8"):
        find_hands(np.zeros((4, 24, 32, 3), dtype=np.float32))


def test_missing_mediapipe_is_one_clear_line(monkeypatch):
    monkeypatch.setitem(sys.modules, "mediapipe", None)  # import mediapipe -> ImportError
    with pytest.raises(ImportError) as error:
        find_hands(np.zeros((2, 24, 32, 3), dtype=np.uint8))
    assert str(error.value) == hand_landmarks.MISSING_MEDIAPIPE
    assert "\n" not in str(error.value)


def test_missing_model_file_is_a_clear_error(monkeypatch):
    def no_distribution(name):
        raise hand_landmarks.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(hand_landmarks.metadata, "distribution", no_distribution)
    monkeypatch.setattr(hand_landmarks.metadata, "distributions", lambda: [])
    with pytest.raises(FileNotFoundError, match="hand_landmarker.task"):
        hand_model_path()


def test_a_model_file_that_is_not_the_official_one_is_refused(monkeypatch, tmp_path):
    fake = tmp_path / "hand_tracking" / "hand_landmarker.task"
    fake.parent.mkdir()
    fake.write_bytes(b"not a model")

    class Distribution:
        files = [PurePosixPath("hand_tracking/hand_landmarker.task")]

        def locate_file(self, path):
            return tmp_path / path

    monkeypatch.setattr(hand_landmarks.metadata, "distribution", lambda name: Distribution())
    with pytest.raises(ValueError, match="sha256"):
        hand_model_path()


def test_the_installed_model_is_found():
    pytest.importorskip("mediapipe")
    path = hand_model_path()
    assert path.name == "hand_landmarker.task" and path.stat().st_size > 1_000_000


@pytest.fixture(scope="module")
def real_clips():
    pytest.importorskip("mediapipe")
    if not (FOOTAGE / "annotations.json").is_file():
        pytest.skip(f"no real footage at {FOOTAGE}")
    from warpskill.data.boxes.clips import read_footage

    return {clip.clip_id: clip for clip in read_footage(FOOTAGE, ["2", "3201", "80962"])}


def test_the_hand_is_found_in_a_real_clip(real_clips):
    from warpskill.bench.footage import SAME_OBJECT_IOU
    from warpskill.data.boxes.overlap import box_ious

    clip = real_clips["2"]
    landmarks = choose_hand(find_hands(clip.frames))
    assert landmarks.shape == (len(clip.frames), 21, 2)
    boxed = np.isfinite(clip.boxes["hand"][:, 0])
    own = hand_masks(landmarks, clip.frames.shape[1:3], forearm=False)
    ious = box_ious(own, clip.boxes["hand"])[boxed]
    assert (ious >= SAME_OBJECT_IOU).mean() >= 0.8, np.round(ious, 2)
    masks = hand_masks(landmarks, clip.frames.shape[1:3], forearm=True)
    assert (masks | own).sum() == masks.sum()  # the forearm only adds to the hand
    breadth, length = np.nanmedian(hand_measurements(landmarks), axis=0)
    assert 1.5 < length / breadth < 3.5  # an adult hand: ~19 / 8.5 cm


def test_no_hand_is_found_in_a_real_clip_without_one(real_clips):
    frames = real_clips["3201"].frames  # the camera moves away from a mouse on a desk
    tracks = find_hands(frames)
    assert not tracks.present().any()
    assert np.isnan(choose_hand(tracks)).all()
    assert hand_regions.hand_regions(frames, tracks).any(axis=(1, 2)).mean() <= 0.1


def test_a_finger_mediapipe_misses_is_found_by_its_skin_and_motion(real_clips):
    from warpskill.bench.footage import SAME_OBJECT_IOU
    from warpskill.data.boxes.overlap import box_ious

    clip = real_clips["80962"]  # a finger alone pokes a toy frog, in a dim light
    tracks = find_hands(clip.frames)
    assert not tracks.present().any()
    regions = hand_regions.hand_regions(clip.frames, tracks)
    boxed = np.isfinite(clip.boxes["hand"][:, 0])
    ious = box_ious(regions, clip.boxes["hand"])[boxed]
    assert (ious >= SAME_OBJECT_IOU).mean() >= 0.6, np.round(ious, 2)  # 18 of 23 when measured
    hand_free = clip.annotated & ~boxed
    assert regions[hand_free].any(axis=(1, 2)).mean() <= 0.1  # none of 35 when measured
