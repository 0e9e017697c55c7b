"""Every optimisation option of the command line reaches the reconstruction on every path.

Each path (``optimize`` of one file, of several, on Ray workers; ``bench something-else``
serially and on Ray; ``run``) is given the same options; the reconstruction it writes must
record exactly those (its ``options``, docs/formats.md) and show them: the known object
height fixes the object's height, ``--init-only`` gives stage (a)'s result.
"""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from warpskill.cli import main
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.data.boxes.something_else import read_something_else, something_else_demonstration
from warpskill.optimizer import LossWeights, OptimizeConfig, OptimizeOptions, optimize
from warpskill.synthetic import make_demonstration

SMALL = dict(image_size=(48, 84), duration=1.5)  # even: an MP4 keeps the width
ASKED = ["--iterations", "2", "--set", "config.init_iterations=3", "--set", "config.weights.grasp_margin=0.01",
         "--seed", "5", "--device", "cpu", "--known", "object_height=0.10", "--object-noun", "mug", "--quiet"]
EXPECTED = OptimizeOptions(device="cpu", seed=5, known={"object_height": 0.10}, object_noun="mug",
                           config=replace(OptimizeConfig(), iterations=2, init_iterations=3,
                                          weights=replace(LossWeights(), grasp_margin=0.01)))
"""The options ``ASKED`` stands for."""


def _cli(*argv) -> tuple[int, str, str]:
    """``warpskill argv`` in-process: (exit status, stdout, stderr)."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main([str(arg) for arg in argv])
    return status, stdout.getvalue(), stderr.getvalue()


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    """Two small synthetic demonstrations, saved: name -> (demonstration, file)."""
    folder = tmp_path_factory.mktemp("demos")
    made = {"pick": make_demonstration("pick_up", seed=0, **SMALL),
            "push": make_demonstration("push_left_to_right", seed=1, **SMALL)}
    for name, demo in made.items():
        demo.save(folder / f"{name}.npz")
    return {name: (demo, folder / f"{name}.npz") for name, demo in made.items()}


def _annotations(folder: Path) -> list[Path]:
    """A Something-Else video of 10 frames (a hand pushing a cup right): its three files."""
    frames = []
    for k in range(1, 11):
        shift = 8 * max(0, k - 3)
        boxes = {"object hand": (10 + shift, 40, 40 + shift, 70), "object 0": (45 + min(shift, 40), 50, 85 + min(shift, 40), 90)}
        labels = [{"box2d": dict(zip(("x1", "y1", "x2", "y2"), box)), "category": name.split()[-1],
                   "gt_annotation": name} for name, box in boxes.items()]
        frames.append({"name": f"7/{k:04d}.jpg", "labels": labels, "gt_placeholders": ["cup"]})
    paths = [folder / "annotations.json", folder / "phases.csv", folder / "actions.csv"]
    paths[0].write_text(json.dumps({"7": frames}))
    paths[1].write_text("video_id,action_id,approach,action,leave\n7,1,1-3,4-8,9-10\n")
    paths[2].write_text("video_id,action\n7,push_left_to_right\n")
    return paths


def _recording(folder: Path, demo) -> list:
    """A video of ``demo``'s masks, its mask folders and contact file: the inputs of ``run``."""
    height, width = demo.image_size
    writer = cv2.VideoWriter(str(folder / "video.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), demo.fps, (width, height))
    if not writer.isOpened():
        pytest.skip("OpenCV cannot write MP4 here")
    for hand, obj in zip(demo.hand_mask, demo.object_mask):
        writer.write(np.repeat((120 * hand + 240 * obj).clip(0, 255).astype(np.uint8)[..., None], 3, axis=2))
    writer.release()
    for role, stack in (("hand", demo.hand_mask), ("object", demo.object_mask)):
        (folder / "masks" / role).mkdir(parents=True)
        for k, mask in enumerate(stack):
            cv2.imwrite(str(folder / "masks" / role / f"{k:04d}.png"), mask.astype(np.uint8) * 255)
    (folder / "contact.csv").write_text("frame,contact\n" + "".join(f"{k},{int(c)}\n" for k, c in enumerate(demo.contact)))
    return [folder / "video.mp4", "--masks", folder / "masks", "--contact", folder / "contact.csv", "--action",
            demo.action, "--no-robot"]


def _optimize_one(demos, tmp_path, flags):
    demo, path = demos["pick"]
    assert _cli("optimize", path, "-o", tmp_path, "--no-pictures", *flags)[0] == 0
    return [(Reconstruction.load(tmp_path / "reconstruction.npz"), demo)]


def _optimize_several(demos, tmp_path, flags):
    assert _cli("optimize", *(path for _, path in demos.values()), "-o", tmp_path, "--no-pictures", *flags)[0] == 0
    return [(Reconstruction.load(tmp_path / name / "reconstruction.npz"), demo) for name, (demo, _) in demos.items()]


def _optimize_on_ray(demos, tmp_path, flags):
    pytest.importorskip("ray")
    demo, path = demos["pick"]
    assert _cli("optimize", path, "-o", tmp_path, "--workers", "1", "--no-pictures", *flags)[0] == 0
    return [(Reconstruction.load(tmp_path / "pick" / "reconstruction.npz"), demo)]


def _something_else(demos, tmp_path, flags, *workers):
    paths = _annotations(tmp_path)
    status, out, err = _cli("bench", "something-else", "--annotations", paths[0], "--phases", paths[1], "--actions",
                            paths[2], "-o", tmp_path / "out", *workers, *flags)
    assert status == 0 and "ERROR" not in out, out + err
    demo, _ = something_else_demonstration(read_something_else(*paths)["7"])
    return [(Reconstruction.load(tmp_path / "out" / "7" / "reconstruction.npz"), demo)]


def _something_else_on_ray(demos, tmp_path, flags):
    pytest.importorskip("ray")
    return _something_else(demos, tmp_path, flags, "--workers", "1")


def _run(demos, tmp_path, flags):
    demo, _ = demos["pick"]
    status, out, err = _cli("run", *_recording(tmp_path, demo), "-o", tmp_path / "out", *flags)
    assert status == 0, out + err
    return [(Reconstruction.load(tmp_path / "out" / "reconstruction.npz"),
             Demonstration.load(tmp_path / "out" / "demonstration.npz"))]


PATHS = {
    "optimize one file": _optimize_one,
    "optimize several files": _optimize_several,
    "optimize --workers 1 (Ray)": pytest.param(_optimize_on_ray, marks=pytest.mark.slow),
    "bench something-else": _something_else,
    "bench something-else --workers 1 (Ray)": pytest.param(_something_else_on_ray, marks=pytest.mark.slow),
    "run": pytest.param(_run, marks=pytest.mark.slow),
}


@pytest.mark.parametrize("init_only", [False, True], ids=["full", "init-only"])
@pytest.mark.parametrize("path", PATHS.values(), ids=PATHS.keys())
def test_every_option_reaches_the_reconstruction(path, init_only, demos, tmp_path):
    expected = replace(EXPECTED, init_only=init_only)
    reconstructions = path(demos, tmp_path, ASKED + ["--init-only"] * init_only)
    for recon, demo in reconstructions:
        assert OptimizeOptions.from_json(str(recon.options)) == expected
        assert recon.object_size[2] == np.float32(0.10)  # the known height, exactly (the optimiser works in float32)
        if init_only:  # stage (a)'s result, as the library gives it
            stage_a = optimize(demo, expected, progress=False)
            for key in ("hand_pos", "object_pos", "object_size", "camera_height", "grasped"):
                np.testing.assert_allclose(getattr(recon, key), getattr(stage_a, key), rtol=1e-4, atol=1e-5,
                                           err_msg=key)


@pytest.mark.slow
def test_run_redoes_a_reconstruction_made_with_other_options(demos, tmp_path):
    demo, _ = demos["pick"]
    argv = ["run", *_recording(tmp_path, demo), "-o", tmp_path / "out", *ASKED, "--init-only"]
    assert _cli(*argv)[0] == 0
    status, out, _ = _cli(*argv[:-1 - len(ASKED)], *ASKED, "--init-only", "--device", "cpu")
    assert status == 0 and "optimize: done, skipped" in out  # the same options: finished
    status, out, _ = _cli(*argv, "--set", "config.init_iterations=4")
    assert status == 0 and "made with other options; redoing the step" in out
    recon = Reconstruction.load(tmp_path / "out" / "reconstruction.npz")
    assert OptimizeOptions.from_json(str(recon.options)).config.init_iterations == 4


@pytest.mark.parametrize("argv, expected", [
    (["bench", "robot", "--source", "optimised", "--init-only"], "--init-only cannot be used here"),
    (["bench", "robot", "--known", "object_height=0.1"], "--known cannot be used here: --source truth optimises nothing"),
    (["bench", "synthetic", "--seed", "3"], "--seed cannot be used here"),
    (["bench", "synthetic", "--init-only"], "--init-only cannot be used here"),
    (["optimize", "x.npz", "-o", "out", "--set", "config.no_such=1"], "OptimizeConfig has no field 'no_such'"),
    (["optimize", "x.npz", "-o", "out", "--set", "iterations"], "--set expects PATH=VALUE"),
    (["optimize", "x.npz", "-o", "out", "--known", "object_height"], "--known expects NAME=METRES"),
], ids=["bench robot --init-only", "bench robot truth --known", "bench synthetic --seed",
        "bench synthetic --init-only", "--set unknown", "--set malformed", "--known without a value"])
def test_an_option_a_path_cannot_honour_is_refused_in_one_line(argv, expected, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = _cli(*argv)
    assert status == 1 and not out
    assert err.startswith("warpskill: error: ") and expected in err and err.count("\n") == 1, err
