"""``warpskill bench speed --clip``: where the seconds of ``warpskill run`` go on a phone clip.

A rendered put_onto (:func:`warpskill.synthetic.make_demonstration`, 640 x 480 at 30 fps,
3.4 s, no mask noise) is painted as a textured video (:mod:`warpskill.synthetic.footage`)
and outlined (hand, object, static box) on a frame where the hand holds the object. Then
``warpskill run CLIP --polygons OUTLINE --action put_onto`` runs on it in fresh processes,
one after another, pinned to the given cores (``taskset``), with the code of this checkout
and, with ``against``, of another (a checkout from before, whose ``run`` fits every frame),
alternating which goes first. The table gives the least seconds of each step over the
repeats (``timing.json``, wall and CPU), the process's start-up (its wall time less its
steps: Python, torch and Warp loading), the whole process (wall and CPU: on a busy machine
the CPU time is the steadier), and each run's verdicts: the
reconstruction's and the replayed robot's.
"""

from __future__ import annotations

import json
import logging
import os
import resource
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from warpskill.bench.report import show
from warpskill.contract import Demonstration, Reconstruction, ResultsFolder, evaluate
from warpskill.synthetic import make_demonstration
from warpskill.synthetic.footage import clip_outline, textured_frames

logger = logging.getLogger(__name__)

ACTION = "put_onto"
CLIP = {"image_size": (480, 640), "fps": 30.0, "duration": 3.4}
"""The clip: a phone's 640 x 480 at 30 fps, 3.4 s."""

STEPS = ("prepare", "optimize", "pictures", "retarget", "replay", "scene")
"""The steps of ``warpskill run`` (``timing.json``), in order."""


@dataclass(frozen=True)
class Clip:
    """The files of the rendered clip: the video, its outline and its ground truth."""

    video: Path
    outline: Path
    truth: Path


def make_clip(folder: Path, seed: int = 0) -> Clip:
    """The rendered put_onto clip in ``folder`` (made once: the ray cast of 103 frames of 640 x 480
    takes a minute; later calls reuse the files), outlined on the middle frame of the contact."""
    clip = Clip(folder / "clip.mp4", folder / "outline.json", folder / "truth.npz")
    if all(path.is_file() for path in (clip.video, clip.outline, clip.truth)):
        return clip
    folder.mkdir(parents=True, exist_ok=True)
    logger.info("rendering the clip (%s, seed %d) into %s", ACTION, seed, folder)
    truth = make_demonstration(ACTION, seed=seed, noise="none", **CLIP)
    frames = textured_frames(truth, seed)
    writer = cv2.VideoWriter(str(clip.video), cv2.VideoWriter_fourcc(*"mp4v"), truth.fps, frames.shape[2:0:-1])
    if not writer.isOpened():
        raise RuntimeError("OpenCV cannot write an MP4 video here")
    for frame in frames:
        writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    writer.release()
    held = np.flatnonzero(truth.contact)
    clip.outline.write_text(json.dumps(clip_outline(truth, int(held[len(held) // 2]))))
    truth.save(clip.truth)
    return clip


def time_run(root: Path, clip: Clip, out: Path, cores: str | None) -> dict:
    """One ``warpskill run`` of the checkout at ``root`` on ``clip`` into ``out`` (emptied first), in a
    fresh process pinned to ``cores`` (e.g. ``"0"``; None: not pinned).

    Returns:
        ``{"seconds", "cpu_seconds": the process's wall and CPU time, "steps": timing.json's steps or {} (a checkout that
        writes none), "reconstruction", "replay": verdicts (True, False; None: not made), "status"}``.
    """
    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, str(Path(__file__).with_name("stage_timing.py")), "run", str(clip.video),
               "--polygons", str(clip.outline), "--action", ACTION, "-o", str(out), "--quiet"]
    if cores is not None:
        command = ["taskset", "-c", cores, *command]
    env = dict(os.environ, PYTHONPATH=str(root), OMP_NUM_THREADS="1")
    start, used = time.perf_counter(), _children_cpu()
    done = subprocess.run(command, env=env, cwd=root, capture_output=True, text=True)
    seconds, cpu_seconds = time.perf_counter() - start, _children_cpu() - used
    if done.returncode not in (0, 3):
        raise RuntimeError(f"warpskill run ({root}) stopped with status {done.returncode}: {done.stderr.strip()}")
    keeper = ResultsFolder(out)
    timing = json.loads(keeper.timing.read_text()) if keeper.timing.is_file() else {"steps": {}}
    recon = keeper.load_finished(keeper.reconstruction, Reconstruction.load)
    replay = keeper.finished_replay()
    return {"seconds": seconds, "cpu_seconds": cpu_seconds, "steps": timing["steps"], "status": done.returncode,
            "frames": None if recon is None else recon.num_frames,
            "reconstruction": None if recon is None else evaluate(recon, ACTION).success,
            "replay": None if replay is None else replay.success}


def _children_cpu() -> float:
    """User and system CPU seconds of this process's finished children."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def bench_clip_speed(folder: str | os.PathLike, *, repeats: int = 3, cores: str | None = "0",
                     against: str | None = None, seed: int = 0) -> dict:
    """Time ``warpskill run`` on the rendered clip (see the module docstring).

    Args:
        folder: where the clip (``clip/``), each run's results (``<label>_<i>/``) and the figures
            (``clip_speed.json``) go.
        repeats: runs per checkout.
        cores: ``taskset`` core list for each run; None: not pinned.
        against: another checkout, run the same way (e.g. a git worktree of the previous commit).
        seed: the scene's seed.

    Returns:
        ``{label: [time_run records]}``, labels ``"this"`` and ``"previous"``.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be at least 1, got {repeats}")
    if cores is not None and shutil.which("taskset") is None:
        raise ValueError("taskset is not installed: give no cores to run unpinned")
    folder = Path(folder).resolve()
    clip = make_clip(folder / "clip", seed)
    roots = {"this": Path(__file__).resolve().parents[2]} | ({"previous": Path(against).resolve()} if against else {})
    runs: dict[str, list[dict]] = {label: [] for label in roots}
    for i in range(repeats):
        for label in sorted(roots, reverse=i % 2 == 1):
            runs[label].append(time_run(roots[label], clip, folder / f"{label}_{i}", cores))
            logger.info("%s run %d: %.1f s", label, i + 1, runs[label][-1]["seconds"])
    (folder / "clip_speed.json").write_text(json.dumps(runs, indent=1))
    _print_table(Demonstration.load(clip.truth), runs, cores)
    return runs


def _print_table(truth: Demonstration, runs: dict[str, list[dict]], cores: str | None) -> None:
    h, w = truth.image_size
    show(f"clip: {ACTION}, {truth.num_frames} frames of {w} x {h} at {truth.fps:g} fps; warpskill run, "
         f"{'cores ' + cores if cores is not None else 'unpinned'}; least of {len(next(iter(runs.values())))} runs")
    show(f"{'step':<10} " + " ".join(f"{label + ' wall / CPU [s]':>26}" for label in runs))
    for step in STEPS:
        cells = []
        for records in runs.values():
            timed = [r["steps"][step] for r in records if step in r["steps"]]
            cells.append(f"{min(t['seconds'] for t in timed):.1f} / {min(t['cpu_seconds'] for t in timed):.1f}"
                         if timed else "-")
        show(f"{step:<10} " + " ".join(f"{cell:>26}" for cell in cells))
    starts = [[r["seconds"] - sum(t["seconds"] for t in r["steps"].values()) for r in records if r["steps"]]
              for records in runs.values()]
    show(f"{'start-up':<10} " + " ".join(f"{min(s):>26.1f}" if s else f"{'-':>26}" for s in starts))
    show(f"{'process':<10} " + " ".join(f"{min(r['seconds'] for r in records):.1f} / "
                                         f"{min(r['cpu_seconds'] for r in records):.1f}".rjust(26)
                                         for records in runs.values()))
    for label, records in runs.items():
        counts = {kind: _verdicts([r[kind] for r in records]) for kind in ("reconstruction", "replay")}
        frames = sorted({r["frames"] for r in records if r["frames"] is not None})
        show(f"{label}: {'/'.join(map(str, frames))} frames fitted; reconstruction {counts['reconstruction']}, "
             f"replay {counts['replay']}")


def _verdicts(successes: list[bool | None]) -> str:
    """``"success 3/3"``, ``"success 2/3, failure 1/3"``, ``"none 3/3"``..."""
    names = ["none" if s is None else "success" if s else "failure" for s in successes]
    return ", ".join(f"{name} {names.count(name)}/{len(names)}" for name in sorted(set(names), key=names.index))
