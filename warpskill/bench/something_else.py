"""``warpskill bench something-else``: the paper's success table on real demonstrations.

Every video of the annotation files is turned into a demonstration
(:mod:`warpskill.data.box_annotations`), reconstructed and evaluated. Per video, ``OUT/<id>/``
receives ``notes.txt`` (what was done about messy annotations), ``reconstruction.npz``
and the pictures. A video that fails is reported with its reason and counts as a failure
in the table; the run goes on. A video whose ``reconstruction.npz`` is finished (loads:
:class:`~warpskill.contract.results_folder.ResultsFolder`) is not reconstructed again,
only evaluated; a corrupt one is redone. With ``workers`` the videos are reconstructed over
Ray (:func:`warpskill.cluster.optimize_folder`), that many at a time, under one progress bar.

With ``robot``, every reconstruction then goes through the robot step of ``warpskill bench
robot`` (:func:`warpskill.bench.end_to_end.robot_step`): a Panda plan (or the reason there is
none, one line), its replay in MuJoCo and Newton judged by the same criteria, kept as
``OUT/<id>/plan.npz`` and ``replay_<engine>.npz`` (and ``replay.mp4`` with ``video``). The
table then has the rows ``planned``, ``replay <engine>`` and ``end to end`` (the
reconstruction and every replay meet the criteria), and a per-video table follows it.
"""

from __future__ import annotations

import dataclasses
import os
import statistics
import time
import traceback
from pathlib import Path
from typing import Sequence

from warpskill.bench.end_to_end import (
    ENGINES,
    RobotOutcome,
    agreement,
    agreement_line,
    one_line,
    robot_rows,
    robot_step,
    timing_lines,
)
from warpskill.bench.outcomes import CaseOutcome, folder_outcomes, judged, record_failure, record_outcomes, write_notes
from warpskill.bench.rulers import hand_ruler_ratio
from warpskill.cluster import INSTALL_HINT, optimize_folder, ray_available
from warpskill.contract.evaluation import evaluate, success_table
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder
from warpskill.data.box_annotations import (
    SomethingElseVideo,
    read_something_else,
    something_else_demonstration,
)
from warpskill.data.box_annotations import (
    object_noun as video_noun,
)
from warpskill.nouns.typical import HAND_LENGTH, size_ratio
from warpskill.optimizer.options import OptimizeOptions
from warpskill.optimizer.pipeline import optimize
from warpskill.robot import prefer_headless_gl
from warpskill.visual.pictures import save_pictures

ROW = "full method (box masks)"
NEAR_TYPICAL = 1.5
"""An object's largest edge within this factor of its noun's typical one counts as its real size."""


def bench_something_else(
    annotations: str | os.PathLike,
    phases: str | os.PathLike,
    actions: str | os.PathLike,
    options: OptimizeOptions | None = None,
    *,
    out: str | os.PathLike,
    videos: list[str] | None = None,
    pictures: bool = True,
    workers: int | None = None,
    address: str | None = None,
    robot: bool = False,
    engines: Sequence[str] = ENGINES,
    video: bool = False,
    baseline: str | os.PathLike | None = None,
    save_baseline: str | os.PathLike | None = None,
) -> dict:
    """Reconstruct and evaluate every annotated video; print progress and the table.

    Args:
        annotations, phases, actions: the files of :func:`~warpskill.data.box_annotations.read_something_else`.
        out: output folder (``OUT/<video_id>/``).
        options: the optimisation options (:class:`OptimizeOptions`), the same on both paths;
            default: all defaults. Its device is also Newton's with ``robot``.
        videos: a subset of video ids; None for all.
        pictures: write the pictures of each reconstruction.
        workers: reconstruct over Ray, this many videos at a time (one per core); None: one
            after the other in this process. Without Ray installed, says how to get it and
            runs serially.
        address: a Ray cluster to join (default ``RAY_ADDRESS``; none: a local Ray).
        robot: also plan each reconstruction for the Panda and replay it (see above).
        engines: the replay engines of ``robot``.
        video: with ``robot``, also write ``OUT/<id>/replay.mp4`` (MuJoCo's rendering of the plan).
        baseline, save_baseline: see :func:`warpskill.bench.outcomes.record_outcomes`; the
            per-video outcome table is written to ``OUT/outcomes.json`` in any case.

    Returns:
        ``{"rows": {row: [(action, success)]}, "failures": {video_id: reason},
        "seconds": {video_id: seconds}, "wall_seconds": seconds}`` (``seconds``: each video's
        reconstruction, both stages, where this run made it); with ``robot`` also
        ``"robot": {video_id: RobotOutcome or None}`` and ``"agreement"``
        (:func:`~warpskill.bench.end_to_end.agreement`); ``"outcomes"`` (the
        :class:`~warpskill.bench.outcomes.CaseOutcome` of each video); and ``"size_ratios"``
        (:func:`noun_size_ratios`).
    """
    table = read_something_else(annotations, phases, actions)
    unknown = sorted(set(videos or ()) - set(table))
    if unknown:
        raise ValueError(f"videos not in the annotation files: {', '.join(unknown)}")
    out = Path(out)
    wall = time.perf_counter()
    options = options or OptimizeOptions()
    step = _RobotStep(engines, options.device or "cpu", video) if robot else None
    if workers is not None or address:
        if ray_available():
            result = _bench_on_ray(table, videos or list(table), out, options, pictures, workers, address, step)
            return _with_outcomes(result, out, table, videos or list(table), baseline, save_baseline,
                                  options.object_noun)
        print(f"--workers needs Ray, which is not installed ({INSTALL_HINT}): running serially")
    results, failures, seconds = [], {}, {}
    for vid in videos or list(table):
        video, folder, start = table[vid], out / vid, time.perf_counter()
        try:
            recon, status, notes = _reconstruct(video, folder, options, pictures, seconds)
            evaluation = evaluate(recon, video.action)
        except Exception as exc:  # one bad video must not stop the benchmark: report it, go on
            failures[vid] = record_failure(folder, exc)
            _count_failure(results, step, vid, video.action, failures[vid])
            continue
        took = f"{time.perf_counter() - start:.1f} s" + (f" ({seconds[vid]:.1f} s reconstructing)" if vid in seconds else "")
        _count(results, step, vid, evaluation, f"{status}, {took}, {len(notes)} note(s)", recon, folder)
    result = _report(results, failures, seconds, time.perf_counter() - wall, "serial, in this process", step)
    return _with_outcomes(result, out, table, videos or list(table), baseline, save_baseline, options.object_noun)


def _demonstration(video, folder: Path):
    """A video's demonstration and notes (:func:`something_else_demonstration`), the notes
    written to ``folder/notes.txt``.

    Raises:
        ValueError: the video has no action.
    """
    if video.action is None:
        raise ValueError("no action in the actions file")
    demo, notes = something_else_demonstration(video)
    write_notes(folder, notes)
    return demo, notes


def _reconstruct(video, folder: Path, options: OptimizeOptions, pictures: bool,
                 seconds: dict[str, float]) -> tuple[Reconstruction, str, list[str]]:
    """A video's reconstruction in ``folder`` (the finished one there, or optimised, saved and
    pictured), its status and the demonstration's notes; the optimisation's time [s] goes to
    ``seconds[video id]``."""
    demo, notes = _demonstration(video, folder)
    keeper = ResultsFolder(folder)
    with keeper.locked():
        recon = keeper.finished_reconstruction(options.to_json())
        if recon is not None:
            return recon, "done before", notes
        optimizing = time.perf_counter()
        recon = optimize(demo, options, progress=False, checkpoint=keeper.checkpoint)
        seconds[video.video_id] = time.perf_counter() - optimizing
        keeper.save(recon, keeper.reconstruction)
        if pictures:
            save_pictures(recon, demo, folder)
    return recon, "reconstructed", notes


def _count(results: list, step, vid: str, evaluation, detail: str, recon: Reconstruction, folder: Path) -> None:
    """Count a video's evaluation in ``results``, print its line (the verdict, then ``detail``) and
    run the robot step on it."""
    results.append((evaluation.action, evaluation.success))
    print(f"{vid:>6} {evaluation.action:<20} {judged(vid, evaluation).verdict()}  {detail}", flush=True)
    if step is not None:
        step.run(vid, evaluation.action, recon, evaluation.success, folder)


def _count_failure(results: list, step, vid: str, action: str | None, reason: str) -> None:
    """Count a video that has no evaluation as a failure (one without an action has no column in
    the table) and print why."""
    if action:
        results.append((action, False))
        if step is not None:
            step.skip(vid, action)
    print(f"{vid:>6} {action or '?':<20} ERROR {reason}", flush=True)


def _with_outcomes(result: dict, out: Path, table, vids, baseline, save_baseline, object_noun) -> dict:
    """The run's result with its per-video outcomes and size ratios added, written to ``out``,
    compared with ``baseline``."""
    cases = {vid: table[vid].action for vid in vids if table[vid].action}
    ratios = noun_size_ratios(out, {vid: object_noun or video_noun(table[vid]) for vid in vids})
    by_hand = hand_size_ratios(out, {vid: table[vid] for vid in vids})
    outcomes = [_with_size_and_robot(o, {"noun_ratio": ratios.get(o.case), "hand_ratio": by_hand.get(o.case)},
                                     result.get("robot"))
                for o in folder_outcomes(out, cases, result["failures"])]
    record_outcomes(out, outcomes, baseline=baseline, save_baseline=save_baseline)
    return {**result, "outcomes": outcomes, "size_ratios": ratios, "hand_ratios": by_hand}


def _with_size_and_robot(outcome: CaseOutcome, size_ratios: dict[str, float | None],
                         robots: dict | None) -> CaseOutcome:
    """A video's outcome with its size ratios (``noun_ratio``, ``hand_ratio``; None: not measured) and
    (where the robot step ran) the robot's record."""
    errors = {**outcome.errors, **{key: ratio for key, ratio in size_ratios.items() if ratio is not None}}
    if robots is None or outcome.case not in robots:
        return dataclasses.replace(outcome, errors=errors)
    robot = robots[outcome.case]
    record = robot.record() if robot is not None else {"planned": False, "replays": {}, "robust": None,
                                                        "misses": ["no reconstruction"], "substitute": ""}
    return dataclasses.replace(outcome, errors=errors, robot=record)


def noun_size_ratios(out: Path, nouns: dict[str, str | None]) -> dict[str, float | None]:
    """Each reconstructed object's size against its noun's typical size
    (:func:`~warpskill.nouns.typical.size_ratio`; None: no typical size), per video id with a
    reconstruction in ``out``; prints their median. ``nouns``: video id -> the object's noun."""
    ratios = {}
    for vid, noun in nouns.items():
        path = out / vid / ResultsFolder.RECONSTRUCTION
        if path.exists():
            ratios[vid] = size_ratio(Reconstruction.load(path).object_size, noun)
    known = [ratio for ratio in ratios.values() if ratio is not None]
    unknown = [f"{vid} ({nouns[vid] or 'no noun'})" for vid, ratio in ratios.items() if ratio is None]
    if known:
        print(f"object size / its noun's typical size (largest edge): {_spread(known)}"
              + (f"; no typical size: {', '.join(unknown)}" if unknown else ""))
        far = [f"{vid} {nouns[vid]} {ratio:.2f}x" for vid, ratio in ratios.items()
               if ratio is not None and not 1 / NEAR_TYPICAL <= ratio <= NEAR_TYPICAL]
        if far:
            print(f"  beyond {NEAR_TYPICAL:g}x: {', '.join(far)}")
    return ratios


def hand_size_ratios(out: Path, videos: dict[str, SomethingElseVideo]) -> dict[str, float | None]:
    """Each reconstructed object's size against the hand's measure of it
    (:func:`~warpskill.bench.rulers.hand_ruler_ratio`; None: no frame to measure), per video id
    with a reconstruction in ``out``; prints their median."""
    ratios = {}
    for vid, video in videos.items():
        path = out / vid / ResultsFolder.RECONSTRUCTION
        if path.exists() and video.action:
            demo, _ = something_else_demonstration(video)
            ratios[vid] = hand_ruler_ratio(Reconstruction.load(path).object_size, demo)
    known = [ratio for ratio in ratios.values() if ratio is not None]
    if known:
        print(f"object size / the hand's measure of it (object box over hand box, a hand {HAND_LENGTH * 100:.0f} cm "
              f"long): {_spread(known)}")
    return ratios


def _spread(ratios: list[float]) -> str:
    """'median 1.05x (0.83-2.38x over 18 videos, 15 within 1.5x)' of size ratios."""
    within = sum(1 / NEAR_TYPICAL <= ratio <= NEAR_TYPICAL for ratio in ratios)
    return (f"median {statistics.median(ratios):.2f}x ({min(ratios):.2f}-{max(ratios):.2f}x over {len(ratios)} "
            f"videos, {within} within {NEAR_TYPICAL:g}x)")


def _bench_on_ray(table, vids, out: Path, options, pictures, workers, address, step) -> dict:
    """The videos' demonstrations built here, reconstructed over Ray, then evaluated here."""
    wall = time.perf_counter()
    results, failures, seconds, demos, notes = [], {}, {}, {}, {}
    for vid in vids:
        try:
            demos[vid], notes[vid] = _demonstration(table[vid], out / vid)
        except Exception as exc:
            failures[vid] = record_failure(out / vid, exc)
    summary = optimize_folder(demos, out, options, workers=workers, address=address, progress=True,
                              postprocess=save_pictures if pictures else None)
    for vid in vids:
        video = table[vid]
        outcome = summary.outcomes.get(vid)
        try:
            if vid in failures:
                raise RuntimeError(failures[vid])
            if not outcome.ok:
                raise RuntimeError(outcome.reason)
            recon = Reconstruction.load(outcome.reconstruction)
            evaluation = evaluate(recon, video.action)
        except Exception as exc:
            if vid not in failures:
                failures[vid] = str(exc) if isinstance(exc, RuntimeError) else f"{type(exc).__name__}: {exc}"
            _count_failure(results, step, vid, video.action, failures[vid])
            continue
        if outcome.status == "done":
            seconds[vid] = outcome.optimize_seconds
        status = "reconstructed" if outcome.status == "done" else outcome.status
        _count(results, step, vid, evaluation, f"{status}, {outcome.seconds:.1f} s in its task "
               f"({outcome.cpu_seconds:.1f} s CPU, {outcome.optimize_seconds:.1f} s reconstructing), "
               f"{len(notes[vid])} note(s)", recon, out / vid)
    cpu = sum(o.cpu_seconds for o in summary.outcomes.values())
    where = f"{summary.workers} Ray worker(s), Ray start-up {summary.startup_seconds:.1f} s, {cpu:.1f} s CPU in the tasks"
    return _report(results, failures, seconds, time.perf_counter() - wall, where, step)


class _RobotStep:
    """The robot step per video (:func:`robot_step`), its printed line and the outcomes so far."""

    def __init__(self, engines: Sequence[str], device: str, video: bool):
        prefer_headless_gl()
        self.engines, self.device, self.video = tuple(engines), device, video
        self.cases: list = []  # (video_id, action, reconstruction ok, outcome or None)

    def run(self, vid: str, action: str, recon, reconstructed: bool, folder: Path) -> None:
        try:
            outcome = robot_step(recon, folder, engines=self.engines, device=self.device, video=self.video)
            line = outcome.summary()
        except Exception as exc:  # a messy real scene must not stop the benchmark either
            outcome = RobotOutcome(reason=f"{type(exc).__name__}: {one_line(exc)}")
            (folder / "robot_error.txt").write_text(traceback.format_exc())
            line = f"robot step failed ({outcome.reason})"
        self.cases.append((vid, action, reconstructed, outcome))
        print(f"{'':>6} {'robot':<20} {line[:200]}", flush=True)

    def skip(self, vid: str, action: str) -> None:
        """A video without a reconstruction: every robot column fails."""
        self.cases.append((vid, action, False, None))

    def report(self) -> dict:
        outcomes = [outcome for *_, outcome in self.cases]
        print()
        print("| video | action | reconstruction | plan | " + " | ".join(f"{e} replay" for e in self.engines) + " |")
        print("| --- | --- | --- | --- | " + " | ".join("---" for _ in self.engines) + " |")
        for vid, action, reconstructed, outcome in self.cases:
            if outcome is None:
                plan = "no reconstruction"
            elif outcome.planned:
                plan = "found"
            else:
                plan = f"none: {outcome.reason}".replace("|", "/")
            cells = [_verdict(outcome, engine) for engine in self.engines]
            print(f"| {vid} | {action} | {'ok' if reconstructed else 'fail'} | {plan} | " + " | ".join(cells) + " |")
        end = [reconstructed and outcome is not None and outcome.replayed for _, _, reconstructed, outcome in self.cases]
        if end:
            print(f"\nend to end (reconstruction and every replay meet the criteria): {sum(end)}/{len(end)} "
                  f"({100.0 * sum(end) / len(end):.1f} %)")
        for line in timing_lines(outcomes):
            print(line)
        line = agreement_line(outcomes)
        if line:
            print(line)
        return {"robot": {vid: outcome for vid, _, _, outcome in self.cases}, "agreement": agreement(outcomes)}


def _verdict(outcome: RobotOutcome | None, engine: str) -> str:
    """A per-video table cell: ``ok``, ``fail (checks)`` or ``-`` (not replayed)."""
    if outcome is None or engine not in outcome.replays:
        return "-"
    return "ok" if outcome.success(engine) else f"fail ({', '.join(outcome.failed_checks(engine))})"


def _report(results, failures, seconds, wall: float, where: str, step: _RobotStep | None = None) -> dict:
    rows = {ROW: results}
    if step is not None:
        rows = robot_rows([(action, ok, outcome) for _, action, ok, outcome in step.cases], step.engines,
                          reconstruction_row=ROW)
    print()
    print(success_table(rows))
    if failures:
        print(f"\n{len(failures)} video(s) failed (counted as failures):")
        for vid, reason in failures.items():
            print(f"  {vid}: {reason}")
    extra = step.report() if step is not None else {}
    print(f"\nwall time: {wall:.1f} s ({where}; {sum(seconds.values()):.1f} s of reconstruction)")
    if seconds:
        print(f"reconstruction (both stages) per video: median {statistics.median(seconds.values()):.1f} s "
              f"({min(seconds.values()):.1f}-{max(seconds.values()):.1f} s)")
    return {"rows": rows, "failures": failures, "seconds": seconds, "wall_seconds": wall, **extra}
