"""Box annotations jittered by a few pixels: bounded, seeded, on every path of bench something-else, and the flips it causes."""

from __future__ import annotations

import hashlib
import json
import types
from pathlib import Path

import numpy as np
import pytest

from warpskill.bench import something_else as bench
from warpskill.bench.cases import Reconstructed
from warpskill.bench.outcomes import load_outcomes
from warpskill.cli import main
from warpskill.contract.reconstruction import Reconstruction
from warpskill.data.boxes.jitter import CORNERS, jittered, video_rng
from warpskill.data.boxes.something_else import read_something_else, something_else_demonstration
from warpskill.synthetic import make_demonstration

ROOT = Path(__file__).resolve().parents[1]
DEV = next((p / "data" / "something_else_dev" for p in (ROOT / "shared", ROOT.parent / "shared")
            if (p / "data" / "something_else_dev").is_dir()), None)


def _label(name, box):
    return {"box2d": dict(zip(CORNERS, box)), "category": "thing", "gt_annotation": name}


def _files(tmp_path, vids=("7", "8")):
    """Two pick-ups of 6 frames: a hand box over an object box; returns the three file paths."""
    frames = {vid: [{"name": f"{vid}/{k:04d}.jpg", "gt_placeholders": ["cup"],
                     "labels": [_label("object hand", [100, 40 + k, 160, 120 + k]),
                                _label("object 0", [120, 100 - 5 * k, 180, 160 - 5 * k])]} for k in range(1, 7)]
              for vid in vids}
    (tmp_path / "a.json").write_text(json.dumps(frames))
    (tmp_path / "p.csv").write_text("video_id,approach,action,leave\n" + "".join(f"{v},1-1,2-6,-\n" for v in vids))
    (tmp_path / "x.csv").write_text("video_id,action\n" + "".join(f"{v},pick_up\n" for v in vids))
    return tmp_path / "a.json", tmp_path / "p.csv", tmp_path / "x.csv"


def _boxes(video) -> np.ndarray:
    """(frames, labels, 4) corners [px]."""
    return np.array([[[label["box2d"][c] for c in CORNERS] for label in entry["labels"]] for entry in video.frames])


def test_jitter_moves_each_corner_by_at_most_px_differently_per_frame_and_video_the_same_per_seed(tmp_path):
    videos = read_something_else(*_files(tmp_path))
    video = videos["7"]
    before = json.dumps(video.frames)
    moved = jittered(video, 2.0, video_rng(0, "7"))
    offsets = _boxes(moved) - _boxes(video)
    assert json.dumps(video.frames) == before  # the video read from the file is left as it is
    assert np.abs(offsets).max() <= 2.0 and np.abs(offsets).max() > 1.0 and np.abs(offsets).min() > 0
    assert len({tuple(frame.ravel()) for frame in offsets}) == len(offsets)  # a draw of its own per frame
    assert np.array_equal(_boxes(jittered(video, 2.0, video_rng(0, "7"))), _boxes(moved))  # reproducible
    assert not np.array_equal(_boxes(jittered(video, 2.0, video_rng(1, "7"))), _boxes(moved))  # another seed
    assert not np.array_equal(_boxes(jittered(videos["8"], 2.0, video_rng(0, "8"))) - _boxes(videos["8"]), offsets)
    assert np.array_equal(_boxes(jittered(video, 0.0, video_rng(0, "7"))), _boxes(video))  # zero: the boxes as they are
    with pytest.raises(ValueError, match="jitter"):
        jittered(video, -1.0, video_rng(0, "7"))


def test_a_box_without_numeric_corners_is_left_for_the_reader_to_report(tmp_path):
    video = read_something_else(*_files(tmp_path))["7"]
    video.frames[0]["labels"][0]["box2d"]["x1"] = None
    moved = jittered(video, 2.0, video_rng(0, "7"))
    assert moved.frames[0]["labels"][0]["box2d"] == video.frames[0]["labels"][0]["box2d"]
    assert moved.frames[0]["labels"][1]["box2d"] != video.frames[0]["labels"][1]["box2d"]


def _expected_masks(paths, vid, px, seed):
    video = read_something_else(*paths)[vid]
    return something_else_demonstration(jittered(video, px, video_rng(seed, vid)))[0].object_mask


def _truth():
    return Reconstruction(**make_demonstration("pick_up", seed=0, noise="none").truth)


def test_the_jittered_boxes_reach_the_serial_and_the_ray_path(tmp_path, monkeypatch):
    paths = _files(tmp_path)
    serial = {}

    def here(video, folder, options, pictures, seconds):
        serial[video.video_id] = something_else_demonstration(video)[0].object_mask
        return Reconstructed(_truth(), "done before")

    monkeypatch.setattr(bench, "reconstruct_here", here)
    bench.bench_something_else(*paths, out=tmp_path / "serial", jitter=3.0, jitter_seed=5)
    on_ray = {}

    def optimize_folder(demos, out, options, **_):
        on_ray.update({vid: demo.object_mask for vid, demo in demos.items()})
        failed = types.SimpleNamespace(ok=False, reason="not run", cpu_seconds=0.0)
        return types.SimpleNamespace(outcomes=dict.fromkeys(demos, failed), workers=2, startup_seconds=0.0)

    monkeypatch.setattr(bench, "ray_available", lambda: True)
    monkeypatch.setattr(bench, "optimize_folder", optimize_folder)
    bench.bench_something_else(*paths, out=tmp_path / "ray", workers=2, jitter=3.0, jitter_seed=5)
    for vid in ("7", "8"):
        expected = _expected_masks(paths, vid, 3.0, 5)
        assert np.array_equal(serial[vid], expected) and np.array_equal(on_ray[vid], expected)
        assert not np.array_equal(expected, _expected_masks(paths, vid, 0.0, 5))
    assert json.loads((tmp_path / "ray" / "jitter.json").read_text()) == {"px": 3.0, "seed": 5}


def test_a_folder_made_with_other_boxes_is_refused_not_reused(tmp_path, monkeypatch, capsys):
    paths = _files(tmp_path, vids=("7",))
    made = tmp_path / "out" / "7" / "reconstruction.npz"
    made.parent.mkdir(parents=True)
    _truth().save(made)
    args = ["bench", "something-else", "--annotations", str(paths[0]), "--phases", str(paths[1]),
            "--actions", str(paths[2]), "-o", str(tmp_path / "out"), "--quiet"]
    assert main([*args, "--jitter", "2"]) == 1
    assert "holds reconstructions made with the boxes as annotated, not boxes jittered by up to 2 px (seed 0)" in \
        capsys.readouterr().err
    assert main([*args, "--jitter", "-1", "-o", str(tmp_path / "other")]) == 1
    assert "jitter: expected a number of pixels >= 0, got -1.0" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.skipif(DEV is None, reason="the shared development data is not next to the repository")
def test_a_jittered_development_video_against_a_baseline_names_its_flip(tmp_path, capsys):
    """One development video, first stage only, jittered by 2 px; a baseline with its verdict the other
    way round (an older table: no margins) makes it a flip, named by the run and by ``bench flips``."""
    annotations = DEV / "annotations.json"
    digest = hashlib.sha256(annotations.read_bytes()).hexdigest()
    args = ["bench", "something-else", "--annotations", str(annotations), "--phases", str(DEV / "phases.csv"),
            "--actions", str(DEV / "actions.csv"), "--videos", "601", "--init-only", "--quiet",
            "--jitter", "2", "-o", str(tmp_path / "j")]
    assert main(args) == 0
    now = load_outcomes(tmp_path / "j")["601"]
    assert now.margins and f"closest calls: 601 ({'ok' if now.success else 'fail'}) {now.closest_text()}" in \
        capsys.readouterr().out
    flipped = {"case": "601", "action": now.action, "success": not now.success,
               "failed_checks": [] if not now.success else ["moved_right"], "errors": {}, "note": "", "robot": None}
    (tmp_path / "base.json").write_text(json.dumps({"cases": [flipped]}))
    assert main([*args, "--baseline", str(tmp_path / "base.json")]) == 0  # the reconstruction is reused
    run = capsys.readouterr().out
    assert main(["bench", "flips", str(tmp_path / "base.json"), str(tmp_path / "j")]) == 0
    flips = capsys.readouterr().out
    way = "broken" if flipped["success"] else "fixed "
    for report in (run, flips):
        assert f"1 case(s) in both, {int(not now.success)} -> {int(now.success)} succeed" in report
        assert f"  {way} 601 " in report
    assert hashlib.sha256(annotations.read_bytes()).hexdigest() == digest  # the annotation file is untouched
