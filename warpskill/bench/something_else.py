"""``warpskill bench something-else``: the paper's success table on real demonstrations.

Every video of the annotation files is turned into a demonstration
(:mod:`warpskill.data.boxes.something_else`), reconstructed and evaluated. Per video, ``OUT/<id>/``
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

With ``jitter``, every box corner is moved by up to that many pixels before the videos are read
(:func:`warpskill.data.boxes.jitter.jittered`, one seeded draw per video and frame), on every
path alike; the annotation file is not touched. ``OUT/jitter.json`` records the jitter, and a
folder whose reconstructions were made with other boxes is refused rather than reused.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import os
import statistics
import time
from pathlib import Path
from typing import Callable, Sequence

from warpskill.bench.cases import Reconstructed, RobotStep, case_demonstration, reconstruct_here, run_case
from warpskill.bench.end_to_end import ENGINES, RobotOutcome, agreement, robot_rows
from warpskill.bench.outcomes import CaseFailed, CaseOutcome
from warpskill.bench.report import record_outcomes, show
from warpskill.bench.rulers import hand_ruler_ratio
from warpskill.cluster import INSTALL_HINT, optimize_folder, ray_available
from warpskill.contract.evaluation import success_table
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder
from warpskill.data.boxes.jitter import jittered, video_rng
from warpskill.data.boxes.something_else import SomethingElseVideo, read_something_else, something_else_demonstration
from warpskill.data.boxes.something_else import object_noun as video_noun
from warpskill.nouns.typical import HAND_LENGTH, size_ratio
from warpskill.optimizer.options import OptimizeOptions
from warpskill.visual.pictures import save_pictures

logger = logging.getLogger(__name__)

ROW = "full method (box masks)"
NEAR_TYPICAL = 1.5
"""An object's largest edge within this factor of its noun's typical one counts as its real size."""
JITTER_FILE = "jitter.json"
"""``OUT/jitter.json``: the jitter the folder's reconstructions were made with (none: no jitter)."""


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
    jitter: float = 0.0,
    jitter_seed: int = 0,
) -> SomethingElseRun:
    """Reconstruct and evaluate every annotated video; log the progress, show the table.

    Every video goes through :func:`~warpskill.bench.cases.run_case`, serially or over Ray
    alike: only where its reconstruction is made differs.

    Args:
        annotations, phases, actions: the files of :func:`~warpskill.data.boxes.something_else.read_something_else`.
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
        baseline, save_baseline: see :func:`warpskill.bench.report.record_outcomes`; the
            per-video outcome table is written to ``OUT/outcomes.json`` in any case.
        jitter: move every box corner by up to this many pixels [px] (0: the boxes as annotated).
        jitter_seed: the seed of the jitter's draws.

    Returns:
        The run's :class:`SomethingElseRun`.

    Raises:
        ValueError: a video not in the files, a negative jitter, or ``out`` holding
            reconstructions made with another jitter.
    """
    table = read_something_else(annotations, phases, actions)
    unknown = sorted(set(videos or ()) - set(table))
    if unknown:
        raise ValueError(f"videos not in the annotation files: {', '.join(unknown)}")
    out, vids, wall = Path(out), videos or list(table), time.perf_counter()
    if jitter:
        table = {vid: jittered(video, jitter, video_rng(jitter_seed, vid)) for vid, video in table.items()}
        logger.info("boxes jittered: every corner by up to %g px in x and y (seed %d)", jitter, jitter_seed)
    _claim_for_jitter(out, {"px": jitter, "seed": jitter_seed} if jitter else None)
    options = options or OptimizeOptions()
    step = RobotStep(engines, options.device or "cpu", video) if robot else None
    seconds: dict[str, float] = {}
    on_ray = (workers is not None or address) and ray_available()
    if (workers is not None or address) and not on_ray:
        logger.warning("--workers needs Ray, which is not installed (%s): running serially", INSTALL_HINT)
    if on_ray:
        made, where = _made_on_ray(table, vids, out, options, pictures, workers, address, seconds)
    else:
        made = {vid: functools.partial(reconstruct_here, table[vid], out / vid, options, pictures, seconds) for vid in vids}
        where = "serial, in this process"
    outcomes = [run_case(vid, table[vid].action, out / vid, made[vid], step) for vid in vids]
    failures = {o.case: o.note for o in outcomes if o.failed_checks == ("error",)}
    wall = time.perf_counter() - wall
    rows = _report([o for o in outcomes if o.action], failures, seconds, wall, where, step)
    ratios = noun_size_ratios(out, {vid: options.object_noun or video_noun(table[vid]) for vid in vids})
    by_hand = hand_size_ratios(out, {vid: table[vid] for vid in vids})
    outcomes = [_with_size_ratios(o, {"noun_ratio": ratios.get(o.case), "hand_ratio": by_hand.get(o.case)})
                for o in outcomes if o.action]
    record_outcomes(out, outcomes, baseline=baseline, save_baseline=save_baseline)
    robots = None if step is None else {vid: outcome for vid, _, _, outcome in step.cases}
    return SomethingElseRun(rows, outcomes, failures, seconds, wall, ratios, by_hand, robots,
                            None if robots is None else agreement(list(robots.values())))


@dataclasses.dataclass(frozen=True)
class SomethingElseRun:
    """What :func:`bench_something_else` found.

    Attributes:
        rows: the success table's rows, row -> [(action, success)] per video with an action.
        outcomes: the :class:`~warpskill.bench.outcomes.CaseOutcome` of each video with an action.
        failures: video id -> why it has no evaluation.
        seconds: video id -> its reconstruction's time [s] (both stages), where this run made it.
        wall_seconds: the whole run [s].
        size_ratios, hand_ratios: video id -> the object's size against its noun's typical one,
            and against the hand's measure of it (:func:`noun_size_ratios`, :func:`hand_size_ratios`).
        robot: with ``robot``, video id -> the robot step's outcome (None: no reconstruction).
        agreement: with ``robot``, how the engines agree (:func:`~warpskill.bench.end_to_end.agreement`).
    """

    rows: dict[str, list[tuple[str, bool]]]
    outcomes: list[CaseOutcome]
    failures: dict[str, str]
    seconds: dict[str, float]
    wall_seconds: float
    size_ratios: dict[str, float | None]
    hand_ratios: dict[str, float | None]
    robot: dict[str, RobotOutcome | None] | None = None
    agreement: dict | None = None


def _claim_for_jitter(out: Path, jitter: dict | None) -> None:
    """Make sure ``out`` holds no reconstruction made with other boxes than ``jitter``'s (None: the
    boxes as annotated), then record ``jitter`` in ``OUT/jitter.json``.

    Raises:
        ValueError: ``out`` has reconstructions made with another jitter (they would be reused).
    """
    marker = out / JITTER_FILE
    made = json.loads(marker.read_text()) if marker.exists() else None
    if made != jitter and any(out.glob(f"*/{ResultsFolder.RECONSTRUCTION}")):
        raise ValueError(f"{out} holds reconstructions made with {_jitter_words(made)}, not {_jitter_words(jitter)}: "
                         "give another output folder (-o)")
    if jitter is None:
        marker.unlink(missing_ok=True)
    else:
        ResultsFolder(out).write_text(marker, json.dumps(jitter) + "\n")


def _jitter_words(jitter: dict | None) -> str:
    """'boxes jittered by up to 2 px (seed 0)' or 'the boxes as annotated'."""
    if jitter is None:
        return "the boxes as annotated"
    return f"boxes jittered by up to {jitter['px']:g} px (seed {jitter['seed']})"


def _made_on_ray(table, vids, out: Path, options, pictures, workers, address,
                 seconds: dict[str, float]) -> tuple[dict[str, Callable[[], Reconstructed]], str]:
    """The videos' demonstrations built here and reconstructed over Ray: per video, what hands
    :func:`~warpskill.bench.cases.run_case` its reconstruction (or raises why there is none); and
    where it ran, in words. The optimisations' times [s] go to ``seconds``."""
    demos, notes, errors = {}, {}, {}
    for vid in vids:
        try:
            demos[vid], notes[vid] = case_demonstration(table[vid], out / vid)
        except Exception as exc:  # raised again by run_case, which records it
            errors[vid] = exc
    summary = optimize_folder(demos, out, options, workers=workers, address=address, progress=True,
                              postprocess=save_pictures if pictures else None)

    def taken(vid: str) -> Reconstructed:
        if vid in errors:
            raise errors[vid]
        task = summary.outcomes[vid]
        if not task.ok:
            raise CaseFailed(task.reason)
        if task.status == "done":
            seconds[vid] = task.optimize_seconds
        return Reconstructed(Reconstruction.load(task.reconstruction),
                             f"{'reconstructed' if task.status == 'done' else task.status}, {task.seconds:.1f} s in "
                             f"its task ({task.cpu_seconds:.1f} s CPU, {task.optimize_seconds:.1f} s reconstructing), "
                             f"{len(notes[vid])} note(s)")

    cpu = sum(o.cpu_seconds for o in summary.outcomes.values())
    where = f"{summary.workers} Ray worker(s), Ray start-up {summary.startup_seconds:.1f} s, {cpu:.1f} s CPU in the tasks"
    return {vid: functools.partial(taken, vid) for vid in vids}, where


def _with_size_ratios(outcome: CaseOutcome, size_ratios: dict[str, float | None]) -> CaseOutcome:
    """A video's outcome with its size ratios (``noun_ratio``, ``hand_ratio``; None: not measured)."""
    errors = {**outcome.errors, **{key: ratio for key, ratio in size_ratios.items() if ratio is not None}}
    return dataclasses.replace(outcome, errors=errors)


def noun_size_ratios(out: Path, nouns: dict[str, str | None]) -> dict[str, float | None]:
    """Each reconstructed object's size against its noun's typical size
    (:func:`~warpskill.nouns.typical.size_ratio`; None: no typical size), per video id with a
    reconstruction in ``out``; shows their median. ``nouns``: video id -> the object's noun."""
    ratios = {}
    for vid, noun in nouns.items():
        path = out / vid / ResultsFolder.RECONSTRUCTION
        if path.exists():
            ratios[vid] = size_ratio(Reconstruction.load(path).object_size, noun)
    known = [ratio for ratio in ratios.values() if ratio is not None]
    unknown = [f"{vid} ({nouns[vid] or 'no noun'})" for vid, ratio in ratios.items() if ratio is None]
    if known:
        show(f"object size / its noun's typical size (largest edge): {_spread(known)}"
             + (f"; no typical size: {', '.join(unknown)}" if unknown else ""))
        far = [f"{vid} {nouns[vid]} {ratio:.2f}x" for vid, ratio in ratios.items()
               if ratio is not None and not 1 / NEAR_TYPICAL <= ratio <= NEAR_TYPICAL]
        if far:
            show(f"  beyond {NEAR_TYPICAL:g}x: {', '.join(far)}")
    return ratios


def hand_size_ratios(out: Path, videos: dict[str, SomethingElseVideo]) -> dict[str, float | None]:
    """Each reconstructed object's size against the hand's measure of it
    (:func:`~warpskill.bench.rulers.hand_ruler_ratio`; None: no frame to measure), per video id
    with a reconstruction in ``out``; shows their median."""
    ratios = {}
    for vid, video in videos.items():
        path = out / vid / ResultsFolder.RECONSTRUCTION
        if path.exists() and video.action:
            demo, _ = something_else_demonstration(video)
            ratios[vid] = hand_ruler_ratio(Reconstruction.load(path).object_size, demo)
    known = [ratio for ratio in ratios.values() if ratio is not None]
    if known:
        show(f"object size / the hand's measure of it (object box over hand box, a hand {HAND_LENGTH * 100:.0f} cm "
             f"long): {_spread(known)}")
    return ratios


def _spread(ratios: list[float]) -> str:
    """'median 1.05x (0.83-2.38x over 18 videos, 15 within 1.5x)' of size ratios."""
    within = sum(1 / NEAR_TYPICAL <= ratio <= NEAR_TYPICAL for ratio in ratios)
    return (f"median {statistics.median(ratios):.2f}x ({min(ratios):.2f}-{max(ratios):.2f}x over {len(ratios)} "
            f"videos, {within} within {NEAR_TYPICAL:g}x)")


def _report(outcomes: list[CaseOutcome], failures: dict[str, str], seconds: dict[str, float], wall: float,
            where: str, step: RobotStep | None = None) -> dict[str, list[tuple[str, bool]]]:
    """Show the success table (with ``step``: the robot's rows, then its tables), the failures and
    the times; returns the table's rows."""
    rows = {ROW: [(o.action, o.success) for o in outcomes]}
    if step is not None:
        rows = robot_rows([(action, ok, outcome) for _, action, ok, outcome in step.cases], step.engines,
                          reconstruction_row=ROW)
    show("", success_table(rows))
    if failures:
        show(f"\n{len(failures)} video(s) failed (counted as failures):",
             *(f"  {vid}: {reason}" for vid, reason in failures.items()))
    if step is not None:
        step.report()
    show(f"\nwall time: {wall:.1f} s ({where}; {sum(seconds.values()):.1f} s of reconstruction)")
    if seconds:
        show(f"reconstruction (both stages) per video: median {statistics.median(seconds.values()):.1f} s "
             f"({min(seconds.values()):.1f}-{max(seconds.values()):.1f} s)")
    return rows
