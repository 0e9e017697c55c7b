"""Mask propagation: polygons JSON and a synthetic video of textured boxes with known masks."""

import json

import cv2
import numpy as np
import pytest

from warpskill.contract.demonstration import DemonstrationError
from warpskill.data.footage.propagation import propagate_masks
from warpskill.data.readers.polygons import read_labelme, read_polygons

MEAN_IOU = 0.9  # measured (seeds 0-2, refined): hand 0.99, object 0.99; 24 frames from the middle one


def _video(n=24, h=96, w=128, seed=0):
    """Two textured boxes (the hand passes over the object) on a textured background."""
    rng = np.random.default_rng(seed)
    background = cv2.GaussianBlur(rng.integers(0, 255, (h, w, 3)).astype(np.uint8), (5, 5), 0)
    sizes, starts, velocities = [(30, 18), (22, 26)], [(10.0, 20.0), (40.0, 70.0)], [(1.5, 1.5), (-0.5, -1.0)]
    textures = [cv2.GaussianBlur(rng.integers(0, 255, (*size, 3)).astype(np.uint8), (3, 3), 0) for size in sizes]
    frames, masks = [], np.zeros((2, n, h, w), dtype=bool)
    for k in range(n):
        frame = background.copy()
        for i in (1, 0):  # the object first, the hand over it
            y = int(round(starts[i][0] + velocities[i][0] * k))
            x = int(round(starts[i][1] + velocities[i][1] * k))
            frame[y : y + sizes[i][0], x : x + sizes[i][1]] = textures[i]
            masks[:, k, y : y + sizes[i][0], x : x + sizes[i][1]] = False
            masks[i, k, y : y + sizes[i][0], x : x + sizes[i][1]] = True
        frames.append(frame)
    return np.stack(frames), masks


def _mean_iou(predicted, truth):
    return np.mean([(p & t).sum() / max((p | t).sum(), 1) for p, t in zip(predicted, truth)])


def test_propagation_keeps_mean_iou_on_a_synthetic_video():
    frames, truth = _video()
    key = len(frames) // 2
    out = propagate_masks(frames, key, {"hand": truth[0, key], "object": truth[1, key]})
    assert np.array_equal(out["hand"][key], truth[0, key])
    ious = [_mean_iou(out[label], truth[i]) for i, label in enumerate(("hand", "object"))]
    assert min(ious) > MEAN_IOU, ious


def test_a_phone_sized_video_is_followed_on_reduced_frames_as_well():
    frames, truth = _video()
    big = np.stack([cv2.resize(frame, None, fx=4, fy=4, interpolation=cv2.INTER_NEAREST) for frame in frames])
    truth = truth.repeat(4, axis=2).repeat(4, axis=3)  # 384 x 512: the flow runs at 240 x 320
    key = len(frames) // 2
    out = propagate_masks(big, key, {"hand": truth[0, key], "object": truth[1, key]})
    assert out["hand"].shape == truth[0].shape and np.array_equal(out["hand"][key], truth[0, key])
    ious = [_mean_iou(out[label], truth[i]) for i, label in enumerate(("hand", "object"))]
    assert min(ious) > MEAN_IOU, ious


def test_propagation_rejects_bad_inputs():
    frames, truth = _video(n=3)
    with pytest.raises(ValueError, match="key_frame"):
        propagate_masks(frames, 5, {"hand": truth[0, 0]})
    with pytest.raises(ValueError, match="shape"):
        propagate_masks(frames, 0, {"hand": truth[0, 0, :10]})
    with pytest.raises(ValueError, match="uint8"):
        propagate_masks(frames.astype(float), 0, {"hand": truth[0, 0]})


def test_read_polygons(tmp_path):
    path = tmp_path / "polygons.json"
    square = [[10, 10], [30, 10], [30, 20], [10, 20]]
    path.write_text(json.dumps({"frame": 3, "hand": square, "object": [[40, 40], [60, 40], [50, 55]],
                                "static": [[[0, 0], [5, 0], [0, 5]], [[70, 50], [80, 50], [80, 64], [70, 64]]]}))
    frame, masks, noun = read_polygons(path, (64, 80))
    assert frame == 3 and noun is None and list(masks) == ["hand", "object", "static_0", "static_1"]
    assert 200 <= int(masks["hand"].sum()) <= 231  # a 20 x 10 px rectangle, edges included
    assert masks["object"][45, 50] and masks["static_0"][1, 1] and masks["static_1"][60, 75]
    assert read_polygons(path, (64, 80), frame=7)[0] == 7
    path.write_text(json.dumps({"frame": 0, "hand": square, "object": square}))  # static may be left out
    assert list(read_polygons(path, (64, 80))[1]) == ["hand", "object"]
    path.write_text(json.dumps({"frame": 0, "object": square, "object_noun": " marker "}))  # the hand to be found
    outline = read_polygons(path, (64, 80))
    assert list(outline.masks) == ["object"] and outline.object_noun == "marker"


def test_read_labelme(tmp_path):
    path = tmp_path / "frame_0012.json"
    tri = [[40, 40], [60, 40], [50, 55]]
    path.write_text(json.dumps({"imagePath": "frames/frame_0012.png", "imageHeight": 64, "imageWidth": 80, "shapes": [
        {"label": "static_b", "points": [[0, 0], [5, 0], [0, 5]], "shape_type": "polygon"},
        {"label": "object", "points": tri, "shape_type": "polygon"},
        {"label": "hand", "points": [[10, 10], [30, 20]], "shape_type": "rectangle"},
        {"label": "static_a", "points": [[70, 50], [80, 50], [80, 64]], "shape_type": "polygon"},
    ]}))
    polygons = read_labelme(path)
    assert polygons["frame"] == 12 and polygons["object"] == tri
    assert polygons["hand"] == [[10, 10], [30, 10], [30, 20], [10, 20]]
    assert polygons["static"] == [[[70, 50], [80, 50], [80, 64]], [[0, 0], [5, 0], [0, 5]]]
    assert read_labelme(path, frame=2)["frame"] == 2
    frame, masks, _ = read_polygons(path, (64, 80))  # detected by its keys
    assert frame == 12 and list(masks) == ["hand", "object", "static_0", "static_1"]
    with pytest.raises(DemonstrationError, match="80 x 64 .* the video's frames are 60 x 50"):
        read_polygons(path, (50, 60))


SQUARE = [[0, 0], [9, 0], [9, 9], [0, 9]]


@pytest.mark.parametrize("content, match", [
    ("{not json", "not valid JSON"),
    ({"hand": SQUARE, "object": SQUARE}, "missing frame"),
    ({"frame": 0, "hand": SQUARE, "object": SQUARE, "objects": []}, "unknown objects"),
    ({"frame": -1, "hand": SQUARE, "object": SQUARE}, "frame: expected a 0-based"),
    ({"frame": 0, "hand": [[0, 0], [1, 0]], "object": SQUARE}, "hand: expected a polygon of at least 3"),
    ({"frame": 0, "hand": SQUARE, "object": SQUARE, "static": SQUARE}, r"static\[0\]: expected a polygon"),
    ({"frame": 0, "hand": SQUARE, "object": [[0, 0], [40, 0], [0, 9]]}, r"object: point \[40, 0\] lies outside the 16 x 16"),
    ({"frame": 0, "hand": SQUARE, "object": [[3, 3], [3.2, 3], [3, 3.2]]}, "object: the polygon encloses 0.02 px\\^2, less than one pixel"),
    ({"shapes": [{"label": "foot", "points": SQUARE}]}, "shapes\\[0\\]: label 'foot'"),
    ({"shapes": [{"label": "hand", "points": SQUARE}], "imagePath": "a7.png"}, "no shape labelled 'object'"),
    ({"shapes": [{"label": "hand", "points": SQUARE}] * 2 + [{"label": "object", "points": SQUARE}],
      "imagePath": "a7.png"}, "2 shapes labelled 'hand'"),
    ({"frame": 0, "object": SQUARE, "object_noun": 3}, "object_noun: expected a non-empty string"),
    ({"shapes": [{"label": "hand", "points": SQUARE}, {"label": "object", "points": SQUARE}], "imagePath": "x.png"},
     "no frame index"),
    ({"shapes": [{"label": "hand", "points": SQUARE, "shape_type": "circle"}]}, "shape_type 'circle'"),
])
def test_read_polygons_rejects_malformed_files(tmp_path, content, match):
    path = tmp_path / "bad.json"
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    with pytest.raises(DemonstrationError, match=match) as error:
        read_polygons(path, (16, 16))
    assert str(path) in str(error.value)
