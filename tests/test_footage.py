"""A phone video outlined without the hand: the model hand drawn with the hand as a ruler, contact
from the landmarks, numbered frames read as a video, and the footage benchmark's scores.

The real-frames path (MediaPipe on ``../shared/data/real_footage``) runs where both are present
and is skipped otherwise.
"""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from warpskill.bench.footage import hurried_outline, score_clip
from warpskill.contract import DemonstrationError
from warpskill.contract.vocabulary import MODEL_HAND_LENGTH, MODEL_HAND_RADIUS
from warpskill.data.boxes.clips import read_footage
from warpskill.data.boxes.overlap import box_iou, box_ious, mask_box
from warpskill.data.contact import IN_CONTACT, NO_CONTACT, UNKNOWN
from warpskill.data.footage.model_hand import model_hand_masks
from warpskill.data.footage.touch import detections_from_landmarks
from warpskill.data.readers.video import is_image_sequence, read_video
from warpskill.nouns.typical import HAND_BREADTH

FOOTAGE = Path(__file__).resolve().parents[2] / "shared" / "data" / "real_footage"


def _hand(wrist=(100.0, 150.0), breadth=20.0, pointing=(0.0, -1.0)):
    """(21, 2) landmarks of an open hand: wrist at ``wrist``, fingers along ``pointing`` [px]."""
    up = np.asarray(pointing, dtype=float) / np.linalg.norm(pointing)
    side = np.array([-up[1], up[0]])
    points = np.zeros((21, 2))
    points[0] = wrist
    for finger in range(5):  # thumb, index, middle, ring, little: base 1, 5, 9, 13, 17
        base = 1 + 4 * finger
        offset = (finger - 2) * breadth / 3.0
        for joint in range(4):
            points[base + joint] = np.asarray(wrist) + up * breadth * (1.0 + 0.5 * joint) + side * offset
    return points


def test_the_model_hand_is_the_cylinder_at_the_scale_the_palm_gives():
    points = _hand(wrist=(100.0, 200.0), breadth=60.0)  # a near hand: 40 cm of arm reach past the image's bottom
    breadth = np.linalg.norm(points[5] - points[17])
    masks = model_hand_masks(np.stack([points, np.full((21, 2), np.nan)]), (240, 200))
    assert not masks[1].any()  # no landmarks, no hand
    rows = masks[0].sum(axis=1)
    band = rows[rows > 0]
    assert np.median(band) == pytest.approx(breadth * 2 * MODEL_HAND_RADIUS / HAND_BREADTH, abs=2)  # edges drawn
    tip_row = np.flatnonzero(rows)[0]
    assert abs(tip_row - points[[4, 8, 12, 16, 20], 1].min()) <= 1.5  # from the farthest fingertip ...
    assert rows[-1] > 0  # ... through the wrist, on along the forearm to the border


def test_model_hand_length_is_the_cylinders_where_the_arm_stays_in_view():
    points = _hand(wrist=(100.0, 60.0), breadth=10.0)  # a small (far) hand high in a tall image
    mask = model_hand_masks(points[None], (600, 200))[0]
    rows = np.flatnonzero(mask.sum(axis=1))
    breadth = np.linalg.norm(points[5] - points[17])
    assert rows[-1] - rows[0] == pytest.approx(MODEL_HAND_LENGTH * breadth / HAND_BREADTH, abs=2)
    assert rows[-1] < 599  # 40 cm of arm at this scale ends inside the image


def test_contact_is_a_fingertip_on_or_at_the_object():
    points = _hand(wrist=(100.0, 150.0), breadth=20.0)
    tip_y = points[[4, 8, 12, 16, 20], 1].min()
    objects = np.zeros((3, 240, 200), dtype=bool)
    objects[0, int(tip_y) - 30 : int(tip_y) + 2, 80:120] = True  # the fingertips on it
    objects[1, 10:30, 10:30] = True  # far away
    landmarks = np.stack([points, points, np.full((21, 2), np.nan)])
    assert list(detections_from_landmarks(landmarks, objects)) == [IN_CONTACT, NO_CONTACT, UNKNOWN]
    with pytest.raises(ValueError, match="expected \\(N, 21, 2\\)"):
        detections_from_landmarks(landmarks[:, :5], objects)


def test_numbered_frames_read_as_a_video(tmp_path):
    for k in range(1, 5):
        cv2.imwrite(str(tmp_path / f"{k:04d}.png"), np.full((8, 10, 3), 40 * k, dtype=np.uint8))
    assert is_image_sequence(tmp_path / "%04d.png") and not is_image_sequence(tmp_path / "clip.mp4")
    frames, fps = read_video(tmp_path / "%04d.png")
    assert frames.shape == (4, 8, 10, 3) and fps == 0.0 and frames[3, 0, 0, 0] == 160
    with pytest.raises(DemonstrationError, match="no image matches"):
        read_video(tmp_path / "%03d.jpg")
    with pytest.raises(FileNotFoundError, match="no such folder of frames"):
        read_video(tmp_path / "absent" / "%04d.png")


def test_box_scores():
    mask = np.zeros((2, 20, 30), dtype=bool)
    mask[0, 5:15, 10:20] = True
    assert list(mask_box(mask[0])) == [10, 5, 20, 15] and np.isnan(mask_box(mask[1])).all()
    assert box_iou(np.array([10, 5, 20, 15.0]), np.array([15, 5, 25, 15.0])) == pytest.approx(1 / 3)
    ious = box_ious(mask, np.array([[10, 5, 20, 15.0], [0, 0, 5, 5]]))
    assert list(ious) == [1.0, 0.0]  # an empty mask on a boxed frame counts 0


def _footage(tmp_path, n=6):
    """A real-footage folder of one clip: a hand box in frames 0-3, none in 4 (annotated), 5 unannotated."""
    (tmp_path / "frames" / "7").mkdir(parents=True)
    entries = []
    for k in range(n):
        cv2.imwrite(str(tmp_path / "frames" / "7" / f"{k + 1:04d}.jpg"), np.zeros((40, 60, 3), np.uint8))
        labels = [{"box2d": {"x1": 10, "y1": 10, "x2": 30, "y2": 30}, "gt_annotation": "object 0", "category": "cup"},
                  {"box2d": {"x1": 40, "y1": 20, "x2": 60, "y2": 40}, "gt_annotation": "object 1", "category": "box"}]
        if k < 4:
            labels.append({"box2d": {"x1": 30, "y1": 0, "x2": 50, "y2": 25}, "gt_annotation": "object hand"})
        if k < n - 1:
            entries.append({"name": f"7/{k + 1:04d}.jpg", "gt_placeholders": ["cup"], "labels": labels})
    (tmp_path / "annotations.json").write_text(json.dumps({"7": entries}))
    return tmp_path


def test_the_footage_format_is_read_and_outlined_as_a_hurried_user_would(tmp_path):
    [clip] = read_footage(_footage(tmp_path))
    assert clip.frames.shape == (6, 40, 60, 3) and clip.noun == "cup"
    assert list(clip.boxes) == ["hand", "object", "static_0"] and list(clip.annotated) == [True] * 5 + [False]
    frame, masks = hurried_outline(clip)
    assert frame == 2 and list(masks) == ["object", "static_0"]  # the middle of frames 0-3, no hand outlined
    assert masks["object"].sum() == 400
    hand = np.zeros((6, 40, 60), dtype=bool)
    hand[:, 0:25, 30:50] = True  # on its box everywhere, so also in the hand-free frame 4
    objects = {"object": np.repeat(masks["object"][None], 6, 0), "static_0": np.zeros((6, 40, 60), bool)}
    score = score_clip(clip, hand, objects, np.zeros(6, bool), 0.1)
    assert list(score.ious["hand"]) == [1.0] * 4 and list(score.ious["static"]) == [0.0] * 5
    assert (score.hand_free, score.hand_free_masked) == (1, 1)
    with pytest.raises(DemonstrationError, match="no clip 8"):
        read_footage(tmp_path, ["8"])


@pytest.mark.skipif(not FOOTAGE.is_dir(), reason="needs ../shared/data/real_footage")
def test_a_real_clip_without_the_hand_outlined_becomes_a_demonstration(tmp_path):
    pytest.importorskip("mediapipe")
    from warpskill.data import read_recording

    [clip] = read_footage(FOOTAGE, ["44862"])  # a glass lifted and turned over
    frame, masks = hurried_outline(clip)
    x0, y0, x1, y1 = mask_box(masks["object"])
    outline = tmp_path / "outline.json"
    outline.write_text(json.dumps({"frame": frame, "object": [[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
                                   "object_noun": "glass"}))
    demo, frames, landmarks, _ = read_recording(FOOTAGE / "frames" / "44862" / "%04d.jpg", polygons=outline,
                                                action="pick_up")
    assert demo.fps == 12.0 and demo.object_noun == "glass" and frames.shape[0] == demo.num_frames == 46
    seen = np.isfinite(landmarks[:, 0, 0])
    assert seen.mean() > 0.8  # the hand holds the glass throughout
    assert (demo.hand_mask.reshape(46, -1).any(1) == seen).all()
    assert demo.contact.any()
    on_box = np.mean(box_ious(demo.object_mask, clip.boxes["object"])[np.isfinite(clip.boxes["object"][:, 0])] >= 0.5)
    assert on_box > 0.7


def _cli(*argv):
    import contextlib
    import io

    from warpskill.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(arg) for arg in argv])
    return status, out.getvalue(), err.getvalue()


def test_an_outline_outside_the_frame_is_refused_in_one_line(tmp_path):
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(1, 4):
        cv2.imwrite(str(frames / f"{k:04d}.jpg"), np.full((40, 60, 3), 90, np.uint8))
    outline = tmp_path / "outline.json"
    outline.write_text(json.dumps({"frame": 1, "object": [[10, 10], [70, 10], [70, 30], [10, 30]]}))
    status, _, err = _cli("prepare", frames / "%04d.jpg", "--polygons", outline, "--action", "pick_up",
                          "-o", tmp_path / "out" / "demo.npz")
    assert status == 2 and err.count("\n") == 1, err
    assert f"{outline}: object: point [70, 10] lies outside the 60 x 40 (W x H) video frames" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not FOOTAGE.is_dir(), reason="needs ../shared/data/real_footage")
def test_a_clip_where_no_hand_is_ever_found_is_refused_and_nothing_is_written(tmp_path):
    pytest.importorskip("mediapipe")
    [clip] = read_footage(FOOTAGE, ["3201"])  # the camera moves away from a mouse; no hand
    frame, masks = hurried_outline(clip)
    x0, y0, x1, y1 = mask_box(masks["object"])
    outline = tmp_path / "outline.json"
    outline.write_text(json.dumps({"frame": frame, "object": [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]}))
    out = tmp_path / "run"
    status, _, err = _cli("run", FOOTAGE / "frames" / "3201" / "%04d.jpg", "--polygons", outline,
                          "--action", "push_left_to_right", "-o", out)
    assert status == 2 and err.count("\n") == 1, err
    assert "no hand found in any of its 43 frames; outline the hand on one frame" in err
    assert not out.exists() or not any(out.iterdir())
