"""``warpskill bench something-else``: the paper's success table on real demonstrations.

Every video of the annotation files is turned into a demonstration
(:mod:`warpskill.data.box_annotations`), reconstructed and evaluated. Per video, ``OUT/<id>/``
receives ``notes.txt`` (what was done about messy annotations), ``reconstruction.npz``
and the pictures. A video that fails is reported with its reason and counts as a failure
in the table; the run goes on. A video whose ``reconstruction.npz`` exists is not
reconstructed again, only evaluated.
"""

from __future__ import annotations

import os
import time
import traceback
from pathlib import Path

from warpskill.contract.evaluation import evaluate, success_table
from warpskill.contract.reconstruction import Reconstruction
from warpskill.data.box_annotations import (
    read_something_else,
    something_else_demonstration,
)

ROW = "full method (box masks)"


def bench_something_else(
    annotations: str | os.PathLike,
    phases: str | os.PathLike,
    actions: str | os.PathLike,
    *,
    out: str | os.PathLike,
    iterations: int | None = None,
    device: str = "cpu",
    videos: list[str] | None = None,
    pictures: bool = True,
) -> dict:
    """Reconstruct and evaluate every annotated video; print progress and the table.

    Args:
        annotations, phases, actions: the files of :func:`~warpskill.data.box_annotations.read_something_else`.
        out: output folder (``OUT/<video_id>/``).
        iterations: physics-stage iterations; None for the library's default.
        device: ``"cpu"`` or ``"cuda"``.
        videos: a subset of video ids; None for all.
        pictures: write the pictures of each reconstruction.

    Returns:
        ``{"rows": {row: [(action, success)]}, "failures": {video_id: reason},
        "seconds": {video_id: seconds}}``.
    """
    from warpskill.optimizer.pipeline import optimize
    from warpskill.visual.pictures import save_pictures

    table = read_something_else(annotations, phases, actions)
    unknown = sorted(set(videos or ()) - set(table))
    if unknown:
        raise ValueError(f"videos not in the annotation files: {', '.join(unknown)}")
    out = Path(out)
    results, failures, seconds = [], {}, {}
    for vid in videos or list(table):
        video = table[vid]
        folder = out / vid
        start = time.perf_counter()
        try:
            if video.action is None:
                raise ValueError("no action in the actions file")
            demo, notes = something_else_demonstration(video)
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "notes.txt").write_text("".join(note + "\n" for note in notes))
            done = folder / "reconstruction.npz"
            if done.exists():
                recon, status = Reconstruction.load(done), "done before"
            else:
                recon = optimize(demo, device=device, iterations=iterations, progress=False,
                                 checkpoint=folder / "checkpoint.pt")
                recon.save(done)
                if pictures:
                    save_pictures(recon, demo, folder)
                status = "reconstructed"
            evaluation = evaluate(recon, video.action)
        except Exception as exc:  # one bad video must not stop the benchmark: report it, go on
            failures[vid] = f"{type(exc).__name__}: {exc}"
            if folder.exists():
                (folder / "error.txt").write_text(traceback.format_exc())
            if video.action:  # without an action it has no column in the table
                results.append((video.action, False))
            print(f"{vid:>6} {video.action or '?':<20} ERROR {failures[vid]}", flush=True)
            continue
        seconds[vid] = time.perf_counter() - start
        results.append((video.action, evaluation.success))
        failed = [name for name, ok in evaluation.checks.items() if not ok]
        verdict = "ok  " if evaluation.success else "fail (" + ", ".join(failed) + ")"
        print(f"{vid:>6} {video.action:<20} {verdict}  {status}, {seconds[vid]:.1f} s, {len(notes)} note(s)", flush=True)
    rows = {ROW: results}
    print()
    print(success_table(rows))
    if failures:
        print(f"\n{len(failures)} video(s) failed (counted as failures):")
        for vid, reason in failures.items():
            print(f"  {vid}: {reason}")
    return {"rows": rows, "failures": failures, "seconds": seconds}
