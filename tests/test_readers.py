"""Readers of mask folders, label images and videos into demonstrations."""

import cv2
import numpy as np
import pytest

from warpskill.contract.demonstration import DemonstrationError
from warpskill.data.readers.mask_files import (
    davis_palette,
    read_label_images,
    read_mask_folders,
    read_video_demonstration,
)
from warpskill.data.readers.video import read_video

N, H, W = 8, 32, 48


def _labels():
    """(N, H, W) indices: 1 the hand reaching a resting object (2), 3 a static object."""
    labels = np.zeros((N, H, W), dtype=np.uint8)
    labels[:, 20:28, 30:40] = 3
    labels[:, 10:16, 20:26] = 2
    for k in range(N):
        labels[k, 10:16, 2 + 2 * k : 10 + 2 * k] = 1  # touches the object from frame 5 on
    labels[0, 0, 0] = 1  # a speck: cleaned away
    return labels


def _write(folder, images):
    folder.mkdir(parents=True, exist_ok=True)
    for k, image in enumerate(images):
        cv2.imwrite(str(folder / f"{k:05d}.png"), image)


def test_index_label_images_by_the_davis_convention(tmp_path):
    _write(tmp_path, _labels())
    demo = read_label_images(tmp_path, 12.0, action="push_left_to_right")
    assert demo.num_frames == N and demo.num_static == 1 and demo.image_size == (H, W)
    assert not demo.hand_mask[0, 0, 0]  # largest blob only
    assert demo.object_mask[0].sum() == 36 and demo.contact[-1] and not demo.contact[0]


def test_colour_label_images_detected_or_mapped(tmp_path):
    rgb = davis_palette(4)[_labels()]
    _write(tmp_path / "davis", rgb[..., ::-1])
    assert read_label_images(tmp_path / "davis", 12.0).num_static == 1
    colours = np.array([[0, 0, 0], [255, 0, 0], [0, 255, 0], [0, 0, 255]], dtype=np.uint8)[_labels()]
    _write(tmp_path / "custom", colours[..., ::-1])
    mapping = {"hand": (255, 0, 0), "object": (0, 255, 0), "static": [(0, 0, 255)]}
    demo = read_label_images(tmp_path / "custom", 12.0, mapping=mapping, contact=np.ones(N))
    assert demo.contact.all() and demo.static_mask.sum() == N * 80
    with pytest.raises(DemonstrationError, match=r"00000.png: label \(0, 0, 255\) is in no mapping"):
        read_label_images(tmp_path / "custom", 12.0, mapping={"hand": (255, 0, 0), "object": (0, 255, 0)})
    with pytest.raises(DemonstrationError, match="missing \\['object'\\]"):
        read_label_images(tmp_path / "custom", 12.0, mapping={"hand": (255, 0, 0)})
    with pytest.raises(DemonstrationError, match="colours"):
        read_label_images(tmp_path / "custom", 12.0, mapping={"hand": 1, "object": 2})


def test_detections_csv_as_contact(tmp_path):
    _write(tmp_path / "masks", _labels())
    (tmp_path / "c.csv").write_text("frame,in_contact\n" + "".join(f"{k},{int(k >= 2)}\n" for k in range(N)))
    demo = read_label_images(tmp_path / "masks", 12.0, contact=tmp_path / "c.csv")
    assert demo.contact.astype(int).tolist() == [0, 0, 1, 1, 1, 1, 1, 1]


def test_binary_mask_folders(tmp_path):
    labels = _labels()
    for name, index in (("hand", 1), ("object", 2), ("static_0", 3)):
        _write(tmp_path / name, (labels == index).astype(np.uint8) * 255)
    demo = read_mask_folders(tmp_path, 12.0)
    assert demo.num_static == 1 and demo.object_mask[0].sum() == 36
    cv2.imwrite(str(tmp_path / "object" / "00003.png"), np.zeros((H, W + 1), np.uint8))
    with pytest.raises(DemonstrationError, match="00003.png: size"):
        read_mask_folders(tmp_path, 12.0)
    with pytest.raises(FileNotFoundError, match="no such folder"):
        read_mask_folders(tmp_path / "nowhere", 12.0)


def test_unreadable_and_missing_images(tmp_path):
    (tmp_path / "a.png").write_bytes(b"not an image")
    with pytest.raises(DemonstrationError, match="a.png: OpenCV cannot read"):
        read_label_images(tmp_path, 12.0)
    with pytest.raises(FileNotFoundError, match="no mask images"):
        (tmp_path / "empty").mkdir()
        read_label_images(tmp_path / "empty", 12.0)


def test_video_and_masks(tmp_path):
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (2 * W, 2 * H))
    for k in range(N):
        writer.write(np.full((2 * H, 2 * W, 3), 20 * k, np.uint8))
    writer.release()
    frames, fps = read_video(path)
    assert frames.shape == (N, 2 * H, 2 * W, 3) and fps == pytest.approx(10.0)
    _write(tmp_path / "masks", _labels())
    demo, background = read_video_demonstration(path, tmp_path / "masks")
    assert demo.fps == pytest.approx(10.0) and background.shape == (N, H, W, 3)
    _write(tmp_path / "short", _labels()[:5])
    with pytest.raises(DemonstrationError, match="8 frames, but .* holds masks for 5"):
        read_video_demonstration(path, tmp_path / "short", contact=np.ones(5))
    (tmp_path / "bad.avi").write_bytes(b"nope")
    with pytest.raises(DemonstrationError, match="bad.avi: OpenCV read no frames"):
        read_video(tmp_path / "bad.avi")
