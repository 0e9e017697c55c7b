"""Your own recording: ``warpskill prepare`` and ``warpskill run`` on a synthetic textured video.

The video is made here from a ``make_demonstration`` ground truth (a hand picking up a box):
each region is painted with a texture that moves with it over a textured table, so optical
flow can follow it; the polygons of one frame are the outlines of the true masks there.
"""

import contextlib
import io
import json
import time

import cv2
import numpy as np
import pytest

from warpskill.cli import main
from warpskill.cli.common import installed
from warpskill.contract import Demonstration, Reconstruction, evaluate
from warpskill.data import read_recording
from warpskill.visual import contact_sheet
from warpskill.synthetic import make_demonstration

SEED, KEY_FRAME = 1, 6  # annotate a frame where hand and box are both in view
IOU_FLOOR = 0.7  # measured (seed 1, frame 6, 25 frames of 128 x 96): hand 0.90, object 0.79
ROBOT = all(installed(name) for name in ("placo", "mujoco", "example-robot-data"))


# ----------------------------------------------------------------------------- the recording


def _texture(rng, size, base, spread, blur):
    lum = cv2.GaussianBlur(rng.normal(0, 1, (size, size)), (0, 0), blur)
    col = cv2.GaussianBlur(rng.normal(0, 1, (size, size, 3)), (0, 0), blur * 2)
    noise = lum[..., None] / lum.std() + 0.35 * col / col.std()
    return np.clip(np.asarray(base) + spread * noise, 0, 255).astype(np.float32)


def _project(points, truth):
    """World points to pixels (docs/formats.md camera)."""
    e, h = float(truth["camera_elevation"]), float(truth["camera_height"])
    rotation = np.array([[1, 0, 0], [0, -np.sin(e), -np.cos(e)], [0, np.cos(e), -np.sin(e)]]).T  # columns: camera axes
    camera = (points - [0, 0, h]) @ rotation
    uv = camera @ np.asarray(truth["camera_K"]).T
    return uv[:, :2] / uv[:, 2:3]


def _textured_frames(demo, seed=0):
    """(N, H, W, 3) uint8: the table, the static objects, the box and the hand, each textured."""
    rng = np.random.default_rng(seed)
    n, h, w = demo.hand_mask.shape
    size = 512
    table = _texture(rng, size, (110, 120, 135), 40, 2.0)[:h, :w]
    box, hand, static = (_texture(rng, size, base, spread, 1.5)
                         for base, spread in (((200, 110, 50), 45), ((225, 180, 150), 40), ((70, 150, 80), 40)))
    centres = {"object": _project(demo.truth["object_pos"], demo.truth), "hand": _project(demo.truth["hand_pos"], demo.truth)}
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    frames = []
    for k in range(n):
        frame = table.copy()
        for mask in demo.static_mask[:, k]:
            frame[mask] = static[:h, :w][mask]
        for texture, (u, v), mask in ((box, centres["object"][k], demo.object_mask[k]),
                                      (hand, centres["hand"][k], demo.hand_mask[k])):
            moved = cv2.remap(texture, xs - np.float32(u - size / 2), ys - np.float32(v - size / 2), cv2.INTER_LINEAR)
            frame[mask] = moved[mask]
        frames.append(np.clip(frame, 0, 255).astype(np.uint8))
    return np.stack(frames)


def _write_video(path, frames, fps):
    n, h, w, _ = frames.shape
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    if not writer.isOpened():
        pytest.skip("OpenCV cannot write MP4 here")
    for frame in frames:
        writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    writer.release()


def _outline(mask):
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    return [[float(x) + 0.5, float(y) + 0.5] for x, y in max(contours, key=cv2.contourArea)[:, 0]]


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """The video, its polygons on KEY_FRAME, the true demonstration and the frames as read back."""
    folder = tmp_path_factory.mktemp("recording")
    truth = make_demonstration("pick_up", seed=SEED, image_size=(96, 128), duration=2.0, noise="none")
    video = folder / "pick_up.mp4"
    _write_video(video, _textured_frames(truth), truth.fps)
    polygons = folder / "polygons.json"
    polygons.write_text(json.dumps({"frame": KEY_FRAME, "hand": _outline(truth.hand_mask[KEY_FRAME]),
                                    "object": _outline(truth.object_mask[KEY_FRAME]), "static": []}))
    return {"folder": folder, "video": video, "polygons": polygons, "truth": truth}


def _cli(*argv):
    """Run ``warpskill argv`` in-process: (exit status, stdout, stderr)."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main([str(arg) for arg in argv])
    return status, stdout.getvalue(), stderr.getvalue()


def _iou(predicted, truth):
    return float((predicted & truth).sum() / (predicted | truth).sum())


# ----------------------------------------------------------------------------- run, end to end


@pytest.mark.slow
def test_run_end_to_end_and_resume(recording, tmp_path):
    out = tmp_path / "out"
    start = time.perf_counter()
    status, stdout, stderr = _cli("run", recording["video"], "--polygons", recording["polygons"], "--action", "pick_up",
                                  "-o", out, "--iterations", "10", "--quiet")
    elapsed = time.perf_counter() - start
    assert status == 0, stdout + stderr

    demo, truth = Demonstration.load(out / "demonstration.npz"), recording["truth"]
    ious = {"hand": _iou(demo.hand_mask, truth.hand_mask), "object": _iou(demo.object_mask, truth.object_mask)}
    print(f"propagated masks vs truth, IoU over all frames: {ious}; run took {elapsed:.1f} s")
    assert min(ious.values()) > IOU_FLOOR, ious
    assert cv2.imread(str(out / "demo.png")) is not None
    timing = json.loads((out / "timing.json").read_text())  # the seconds of each step, also the last line printed
    assert {"prepare", "optimize", "pictures"} <= set(timing["steps"]) and stdout.splitlines()[-1].startswith("seconds: ")
    assert timing["cpu_seconds"] == pytest.approx(sum(step["cpu_seconds"] for step in timing["steps"].values()))

    recon = Reconstruction.load(out / "reconstruction.npz")
    assert evaluate(recon, "pick_up").success, stdout
    for picture in ("overlay.gif", "top_view.png", "trajectories.png"):
        assert (out / picture).is_file(), picture
    written = ["demonstration.npz", "demo.png", "reconstruction.npz"]
    if ROBOT:
        written += ["plan.npz", "plan.csv", "replay.npz"]
        lines = stdout.splitlines()
        replayed = next(i for i, line in enumerate(lines) if line.startswith(f"replay: {out / 'replay.npz'}"))
        assert lines[replayed + 1] == "pick_up: success", stdout  # the replay's verdict
    else:
        assert "robot steps skipped" in stdout
    mtimes = {name: (out / name).stat().st_mtime_ns for name in written}

    status, stdout, stderr = _cli("run", recording["video"], "--polygons", recording["polygons"], "--action", "pick_up",
                                  "-o", out, "--iterations", "10", "--quiet")
    assert status == 0, stdout + stderr
    steps = ("prepare", "optimize") + (("retarget", "replay") if ROBOT else ())
    for step in steps:
        assert f"{step}: done, skipped" in stdout, stdout
    assert "reconstruction:" not in stdout and "plan:" not in stdout
    assert {name: (out / name).stat().st_mtime_ns for name in written} == mtimes

    if ROBOT:  # a step whose file does not load is redone, the finished ones before it are not
        (out / "replay.npz").write_bytes(b"not a zip")
        status, stdout, stderr = _cli("run", recording["video"], "--polygons", recording["polygons"],
                                      "--action", "pick_up", "-o", out, "--iterations", "10", "--quiet")
        assert status == 0, stdout + stderr
        assert f"{out / 'replay.npz'} is corrupt (" in stdout and f"replay: {out / 'replay.npz'} (mujoco" in stdout, stdout
        assert "retarget: done, skipped" in stdout and (out / "plan.npz").stat().st_mtime_ns == mtimes["plan.npz"]


# ----------------------------------------------------------------------------- each input option


def _save_images(folder, stack):
    folder.mkdir(parents=True)
    for k, image in enumerate(stack):
        cv2.imwrite(str(folder / f"{k:04d}.png"), image.astype(np.uint8))


def test_masks_folders(recording, tmp_path):
    truth = recording["truth"]
    for name, stack in (("hand", truth.hand_mask), ("object", truth.object_mask)):
        _save_images(tmp_path / "masks" / name, stack * 255)
    status, stdout, stderr = _cli("prepare", recording["video"], "--masks", tmp_path / "masks", "--action", "pick_up",
                                  "-o", tmp_path / "demo.npz")
    assert status == 0, stderr
    demo = Demonstration.load(tmp_path / "demo.npz")
    assert _iou(demo.hand_mask, truth.hand_mask) > 0.95 and _iou(demo.object_mask, truth.object_mask) > 0.95
    assert demo.action == "pick_up" and demo.num_static == 0 and demo.contact.any()
    assert f"contact sheet: {tmp_path / 'demo.png'}" in stdout and cv2.imread(str(tmp_path / "demo.png")) is not None


def test_label_images(recording, tmp_path):
    truth = recording["truth"]
    labels = np.where(truth.hand_mask, 1, np.where(truth.object_mask, 2, 0))
    labels[:, 80:, :20] = 3  # a static object in the corner
    _save_images(tmp_path / "labels", labels)
    status, _, stderr = _cli("prepare", recording["video"], "--labels", tmp_path / "labels", "--action", "put_onto",
                             "-o", tmp_path / "demo.npz")
    assert status == 0, stderr
    demo = Demonstration.load(tmp_path / "demo.npz")
    assert demo.num_static == 1 and demo.static_mask[0, :, 85, 10].all() and demo.action == "put_onto"
    assert _iou(demo.object_mask, truth.object_mask) > 0.95


def test_labelme_polygons_with_a_frame_option(recording, tmp_path):
    truth, k = recording["truth"], 10
    labelme = {"imagePath": "pick_up_0003.png", "imageHeight": 96, "imageWidth": 128, "shapes": [
        {"label": "hand", "points": _outline(truth.hand_mask[k]), "shape_type": "polygon"},
        {"label": "object", "points": _outline(truth.object_mask[k]), "shape_type": "polygon"},
        {"label": "static_table_corner", "points": [[0, 80], [20, 80], [20, 96], [0, 96]], "shape_type": "polygon"},
    ]}
    path = tmp_path / "labelme.json"
    path.write_text(json.dumps(labelme))
    demo, frames, *_ = read_recording(recording["video"], polygons=path, action="pick_up", frame=k)
    assert np.array_equal(demo.hand_mask[k], truth.hand_mask[k]) or _iou(demo.hand_mask[k], truth.hand_mask[k]) > 0.9
    assert demo.num_static == 1 and frames.shape == (truth.num_frames, 96, 128, 3)
    # without --frame, the digits of imagePath: frame 3
    status, _, stderr = _cli("prepare", recording["video"], "--polygons", path, "--action", "pick_up",
                             "-o", tmp_path / "demo.npz")
    assert status == 0, stderr
    assert _iou(Demonstration.load(tmp_path / "demo.npz").hand_mask[3], truth.hand_mask[3]) > 0.7


def _box(mask):
    ys, xs = np.nonzero(mask)
    return {"x1": float(xs.min()), "y1": float(ys.min()), "x2": float(xs.max() + 1), "y2": float(ys.max() + 1)}


def test_something_else_boxes(recording, tmp_path):
    truth = recording["truth"]
    entries = []
    for k in range(truth.num_frames):
        labels = [{"box2d": _box(mask[k]), "category": category, "gt_annotation": name}
                  for name, category, mask in (("object hand", "hand", truth.hand_mask), ("object 0", "box", truth.object_mask))
                  if mask[k].any()]
        entries.append({"name": f"42/{k + 1:04d}.jpg", "labels": labels, "gt_placeholders": ["box"]})
    path = tmp_path / "boxes.json"
    path.write_text(json.dumps({"42": entries, "43": entries[:3]}))
    status, _, stderr = _cli("prepare", recording["video"], "--boxes", path, "--video-id", "42", "--action", "pick_up",
                             "-o", tmp_path / "demo.npz")
    assert status == 0, stderr
    demo = Demonstration.load(tmp_path / "demo.npz")
    assert demo.num_frames == truth.num_frames and _iou(demo.object_mask, truth.object_mask) > 0.5
    status, _, stderr = _cli("prepare", recording["video"], "--boxes", path, "--action", "pick_up", "-o", tmp_path / "x.npz")
    assert status == 2 and f"{path}: holds 2 videos; give the video id" in stderr
    status, _, stderr = _cli("prepare", recording["video"], "--boxes", path, "--video-id", "7", "--action", "pick_up",
                             "-o", tmp_path / "x.npz")
    assert status == 2 and "no boxes for video id '7'" in stderr


def test_contact_file_fps_and_intrinsics(recording, tmp_path):
    truth = recording["truth"]
    contact = tmp_path / "contact.csv"
    contact.write_text("frame,contact\n" + "".join(f"{k},{int(on)}\n" for k, on in enumerate(truth.contact)))
    status, _, stderr = _cli("prepare", recording["video"], "--polygons", recording["polygons"], "--contact", contact,
                             "--fps", "24", "--intrinsics", "100", "110", "60", "50", "--action", "pick_up",
                             "-o", tmp_path / "demo.npz")
    assert status == 0, stderr
    demo = Demonstration.load(tmp_path / "demo.npz")
    assert np.array_equal(demo.contact, truth.contact) and demo.fps == 24.0
    assert np.allclose(demo.intrinsics.K, [[100, 0, 60], [0, 110, 50], [0, 0, 1]])


def test_detections_are_filtered(recording, tmp_path):
    truth = recording["truth"]
    on = np.flatnonzero(truth.contact)
    detections = tmp_path / "detections.csv"
    rows = [f"{k},{int(truth.contact[k])},0.9" for k in range(truth.num_frames) if k != on[3]]  # one frame unseen
    rows.append(f"{on[3]},0,0.1")  # ... and one low-score detection of it, ignored
    detections.write_text("frame,in_contact,score\n" + "\n".join(rows) + "\n")
    demo, *_ = read_recording(recording["video"], polygons=recording["polygons"], detections=detections, action="pick_up")
    assert demo.contact[on[3]] and demo.contact[on[0] : on[-1] + 1].all() and not demo.contact[: on[0] - 1].any()


def test_contact_sheet_draws_every_frame_flag(recording, tmp_path):
    truth = recording["truth"]
    path = contact_sheet(truth, None, tmp_path / "sheet.png")
    image = cv2.imread(str(path))
    assert image is not None and image.shape[1] >= 4 * 240
    with pytest.raises(ValueError, match="frames: expected shape"):
        contact_sheet(truth, np.zeros((3, 96, 128, 3), np.uint8), tmp_path / "bad.png")


# ----------------------------------------------------------------------------- bad input


@pytest.fixture(scope="module")
def prepared(recording):
    """A demonstration and its contact sheet, as ``prepare`` writes them (bytes)."""
    out = recording["folder"] / "prepared" / "demo.npz"
    status, _, stderr = _cli("prepare", recording["video"], "--polygons", recording["polygons"], "--action", "pick_up",
                             "-o", out)
    assert status == 0, stderr
    return out.read_bytes(), out.with_suffix(".png").read_bytes()


@pytest.fixture
def existing(prepared, tmp_path):
    """An output written before: a failing command must leave it as it was."""
    out = tmp_path / "demo.npz"
    out.write_bytes(prepared[0])
    out.with_suffix(".png").write_bytes(prepared[1])
    return out, *prepared


def _bad_inputs(recording, tmp):
    video, polygons, truth = recording["video"], recording["polygons"], recording["truth"]
    broken = tmp / "broken.mp4"
    broken.write_bytes(b"\x00\x01 not a video" * 100)
    outside = tmp / "outside.json"
    outside.write_text(json.dumps({"frame": 0, "hand": [[10, 10], [20, 10], [15, 20]],
                                   "object": [[100, 50], [140, 50], [120, 70]], "static": []}))
    small = tmp / "small"
    for name, stack in (("hand", truth.hand_mask[:, ::2, ::2]), ("object", truth.object_mask[:, ::2, ::2])):
        _save_images(small / name, stack * 255)
    short = tmp / "short.csv"
    short.write_text("frame,contact\n" + "".join(f"{k},1\n" for k in range(truth.num_frames - 1)))
    return {
        "missing video": ([tmp / "nothing.mp4", "--polygons", polygons, "--action", "pick_up"],
                          f"{tmp / 'nothing.mp4'}: no such video file"),
        "unreadable frames": ([broken, "--polygons", polygons, "--action", "pick_up"],
                              f"{broken}: OpenCV read no frames"),
        "polygons outside the image": ([video, "--polygons", outside, "--action", "pick_up"],
                                       f"{outside}: object: point [140, 50] lies outside the 128 x 96 (W x H) video frames"),
        "masks of another size": ([video, "--masks", small, "--action", "pick_up"],
                                  f"{small}: masks of {truth.num_frames} frames of 64 x 48 (W x H) px, but {video} has "
                                  f"{truth.num_frames} frames of 128 x 96 px"),
        "contact of the wrong length": ([video, "--polygons", polygons, "--contact", short, "--action", "pick_up"],
                                        f"{short}: {truth.num_frames - 1} contact rows, but the video has "
                                        f"{truth.num_frames} frames"),
        "unknown action": ([video, "--polygons", polygons, "--action", "juggle"], "action: unknown action 'juggle'"),
    }


@pytest.mark.parametrize("case", ["missing video", "unreadable frames", "polygons outside the image",
                                  "masks of another size", "contact of the wrong length", "unknown action"])
@pytest.mark.parametrize("command", ["prepare", "run"])
def test_bad_input_is_one_clear_line(recording, existing, tmp_path, case, command):
    argv, message = _bad_inputs(recording, tmp_path)[case]
    out, demo_bytes, sheet_bytes = existing
    if command == "run":  # a folder holding an unfinished run: the demonstration without its sheet
        folder = tmp_path / "run"
        folder.mkdir()
        (folder / "demonstration.npz").write_bytes(demo_bytes)
        status, stdout, stderr = _cli("run", *argv, "-o", folder)
        assert (folder / "demonstration.npz").read_bytes() == demo_bytes
        assert sorted(path.name for path in folder.iterdir()) == ["demonstration.npz"]
    else:
        status, stdout, stderr = _cli("prepare", *argv, "-o", out)
    assert status == (1 if case == "missing video" else 2), stdout + stderr  # 2: no demonstration in it
    assert stderr.startswith("warpskill: error: ") and message in stderr, stderr
    assert len(stderr.strip().splitlines()) == 1 and "Traceback" not in stderr
    assert out.read_bytes() == demo_bytes and out.with_suffix(".png").read_bytes() == sheet_bytes


def test_the_shipped_example_prepares(tmp_path):
    from warpskill.assets import path

    video, polygons = path("examples/own_recording/pick_up.mp4"), path("examples/own_recording/pick_up_polygons.json")
    status, stdout, stderr = _cli("prepare", video, "--polygons", polygons, "--action", "pick_up", "-o", tmp_path / "demo.npz")
    assert status == 0, stderr
    demo = Demonstration.load(tmp_path / "demo.npz")
    assert demo.num_frames == 25 and demo.image_size == (144, 192) and demo.contact.any()
