"""``warpskill bench something-else``: the paper's success table on real demonstrations.

Every video of the annotation files is turned into a demonstration
(:mod:`warpskill.data.box_annotations`), reconstructed and evaluated. Per video, ``OUT/<id>/``
receives ``notes.txt`` (what was done about messy annotations), ``reconstruction.npz``
and the pictures. A video that fails is reported with its reason and counts as a failure
in the table; the run goes on. A video whose ``reconstruction.npz`` exists is not
reconstructed again, only evaluated. With ``workers`` the videos are reconstructed over
Ray (:func:`warpskill.cluster.optimize_folder`), that many at a time, under one progress bar.
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
    workers: int | None = None,
    address: str | None = None,
) -> dict:
    """Reconstruct and evaluate every annotated video; print progress and the table.

    Args:
        annotations, phases, actions: the files of :func:`~warpskill.data.box_annotations.read_something_else`.
        out: output folder (``OUT/<video_id>/``).
        iterations: physics-stage iterations; None for the library's default.
        device: ``"cpu"`` or ``"cuda"``.
        videos: a subset of video ids; None for all.
        pictures: write the pictures of each reconstruction.
        workers: reconstruct over Ray, this many videos at a time (one per core); None: one
            after the other in this process. Without Ray installed, says how to get it and
            runs serially.
        address: a Ray cluster to join (default ``RAY_ADDRESS``; none: a local Ray).

    Returns:
        ``{"rows": {row: [(action, success)]}, "failures": {video_id: reason},
        "seconds": {video_id: seconds}, "wall_seconds": seconds}``.
    """
    from warpskill.optimizer.pipeline import optimize
    from warpskill.visual.pictures import save_pictures

    table = read_something_else(annotations, phases, actions)
    unknown = sorted(set(videos or ()) - set(table))
    if unknown:
        raise ValueError(f"videos not in the annotation files: {', '.join(unknown)}")
    out = Path(out)
    wall = time.perf_counter()
    if workers is not None or address:
        from warpskill.cluster import INSTALL_HINT
        from warpskill.cluster.runner import ray_available

        if ray_available():
            return _bench_on_ray(table, videos or list(table), out, iterations, device, pictures, workers, address)
        print(f"--workers needs Ray, which is not installed ({INSTALL_HINT}): running serially")
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
    return _report(results, failures, seconds, time.perf_counter() - wall, "serial, in this process")


def _bench_on_ray(table, vids, out: Path, iterations, device, pictures, workers, address) -> dict:
    """The videos' demonstrations built here, reconstructed over Ray, then evaluated here."""
    from warpskill.cluster.runner import optimize_folder
    from warpskill.visual.pictures import save_pictures

    wall = time.perf_counter()
    results, failures, seconds, demos, notes = [], {}, {}, {}, {}
    for vid in vids:
        video = table[vid]
        try:
            if video.action is None:
                raise ValueError("no action in the actions file")
            demos[vid], notes[vid] = something_else_demonstration(video)
            (out / vid).mkdir(parents=True, exist_ok=True)
            (out / vid / "notes.txt").write_text("".join(note + "\n" for note in notes[vid]))
        except Exception as exc:
            failures[vid] = f"{type(exc).__name__}: {exc}"
            if (out / vid).exists():
                (out / vid / "error.txt").write_text(traceback.format_exc())
            if video.action:
                results.append((video.action, False))
    summary = optimize_folder(demos, out, workers=workers, address=address, device=device, iterations=iterations,
                              progress=True, postprocess=save_pictures if pictures else None)
    for vid in vids:
        video = table[vid]
        outcome = summary.outcomes.get(vid)
        try:
            if vid in failures:
                raise RuntimeError(failures[vid])
            if not outcome.ok:
                raise RuntimeError(outcome.reason)
            evaluation = evaluate(Reconstruction.load(outcome.reconstruction), video.action)
        except Exception as exc:
            if vid not in failures:
                failures[vid] = str(exc) if isinstance(exc, RuntimeError) else f"{type(exc).__name__}: {exc}"
                results.append((video.action, False))
            print(f"{vid:>6} {video.action or '?':<20} ERROR {failures[vid]}", flush=True)
            continue
        seconds[vid] = outcome.seconds
        results.append((video.action, evaluation.success))
        failed = [name for name, ok in evaluation.checks.items() if not ok]
        verdict = "ok  " if evaluation.success else "fail (" + ", ".join(failed) + ")"
        status = "reconstructed" if outcome.status == "done" else outcome.status
        print(f"{vid:>6} {video.action:<20} {verdict}  {status}, {outcome.seconds:.1f} s in its task "
              f"({outcome.cpu_seconds:.1f} s CPU), {len(notes[vid])} note(s)", flush=True)
    cpu = sum(o.cpu_seconds for o in summary.outcomes.values())
    where = f"{summary.workers} Ray worker(s), Ray start-up {summary.startup_seconds:.1f} s, {cpu:.1f} s CPU in the tasks"
    return _report(results, failures, seconds, time.perf_counter() - wall, where)


def _report(results, failures, seconds, wall: float, where: str) -> dict:
    rows = {ROW: results}
    print()
    print(success_table(rows))
    if failures:
        print(f"\n{len(failures)} video(s) failed (counted as failures):")
        for vid, reason in failures.items():
            print(f"  {vid}: {reason}")
    print(f"\nwall time: {wall:.1f} s ({where}; {sum(seconds.values()):.1f} s of reconstruction)")
    return {"rows": rows, "failures": failures, "seconds": seconds, "wall_seconds": wall}
