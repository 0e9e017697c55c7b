"""One case of a real-video benchmark, made and judged the same way wherever it is reconstructed.

:func:`run_case` is the one flow of ``bench something-else`` and ``bench second-opinion``:
a video's reconstruction (:func:`reconstruct_here` in this process, or taken from a Ray
task), evaluated (and against a ground truth where there is one), its line logged, then the
robot step (:class:`RobotStep`) -> :class:`~warpskill.bench.outcomes.CaseOutcome`.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path
from typing import Callable, Sequence

from warpskill.bench.end_to_end import RobotOutcome, agreement_line, robot_step, timing_lines
from warpskill.bench.outcomes import (
    CaseOutcome,
    RobotRecord,
    camera_frame_errors,
    failed_case,
    judged,
    record_failure,
    verdict,
    write_notes,
)
from warpskill.bench.report import show
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.evaluation import evaluate
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder
from warpskill.data.boxes.something_else import SomethingElseVideo, something_else_demonstration
from warpskill.optimizer.options import OptimizeOptions
from warpskill.optimizer.pipeline import optimize
from warpskill.robot import prefer_headless_gl
from warpskill.visual.pictures import save_pictures

logger = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class Reconstructed:
    """A video's reconstruction as :func:`run_case` receives it from either path.

    Attributes:
        recon: the reconstruction.
        detail: how it was made (``reconstructed``, ``done before``), how long it took and the
            demonstration's notes, as the video's line says it.
    """

    recon: Reconstruction
    detail: str


def run_case(vid: str, action: str | None, folder: Path, reconstruct: Callable[[], Reconstructed],
             step: RobotStep | None = None, truth: Callable[[], dict] | None = None) -> CaseOutcome:
    """One annotated video of a benchmark (``bench something-else``, ``bench second-opinion``): its
    reconstruction (``reconstruct()``, made in this process or taken from a Ray task), evaluated for
    ``action`` (and, with ``truth()``, its ground truth: the errors, :func:`camera_frame_errors`),
    its line logged, then (with ``step``) the robot step. A video that fails is its reason, its
    traceback kept in ``folder``; one without an action has an empty one (it has no column in the
    table)."""
    try:
        made = reconstruct()
        evaluation = evaluate(made.recon, action)
        errors = camera_frame_errors(made.recon, truth()) if truth is not None else None
    except Exception as exc:  # one bad video must not stop the benchmark: report it, go on
        outcome = failed_case(vid, action or "", record_failure(folder, exc))
        logger.info("%6s %-20s ERROR %s", vid, action or "?", outcome.note)
        return outcome if step is None or not action else dataclasses.replace(outcome, robot=step.skip(vid, action))
    outcome = judged(vid, made.recon, evaluation, errors)
    scale = f", scale {outcome.errors['scale']:.2f}" if "scale" in outcome.errors else ""
    logger.info("%6s %-20s %s  closest %s; %s%s", vid, action, outcome.verdict(), outcome.closest_text(), made.detail,
                scale)
    if step is None:
        return outcome
    return dataclasses.replace(outcome, robot=step.run(vid, action, made.recon, outcome.success, folder))


def case_demonstration(video: SomethingElseVideo, folder: Path) -> tuple[Demonstration, list[str]]:
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


def reconstruct_here(video: SomethingElseVideo, folder: Path, options: OptimizeOptions, pictures: bool,
                     seconds: dict[str, float]) -> Reconstructed:
    """A video's reconstruction in this process: the finished one in ``folder``, or optimised,
    saved and pictured (the optimisation's time [s] goes to ``seconds[video id]``)."""
    start = time.perf_counter()
    demo, notes = case_demonstration(video, folder)
    keeper = ResultsFolder(folder)
    with keeper.locked():
        recon = keeper.finished_reconstruction(options.to_json())
        status = "done before"
        if recon is None:
            optimizing = time.perf_counter()
            recon = optimize(demo, options, progress=False, checkpoint=keeper.checkpoint)
            seconds[video.video_id] = time.perf_counter() - optimizing
            keeper.save(recon, keeper.reconstruction)
            if pictures:
                save_pictures(recon, demo, folder)
            status = "reconstructed"
    took = f"{time.perf_counter() - start:.1f} s"
    if video.video_id in seconds:
        took += f" ({seconds[video.video_id]:.1f} s reconstructing)"
    return Reconstructed(recon, f"{status}, {took}, {len(notes)} note(s)")


class RobotStep:
    """The robot step per video (:func:`robot_step`), its logged line and the outcomes so far."""

    def __init__(self, engines: Sequence[str], device: str, video: bool):
        prefer_headless_gl()
        self.engines, self.device, self.video = tuple(engines), device, video
        self.cases: list = []  # (video_id, action, reconstruction ok, outcome or None)

    def run(self, vid: str, action: str, recon, reconstructed: bool, folder: Path) -> RobotRecord:
        """Plan and replay a video's reconstruction; its record for the outcome table."""
        try:
            outcome = robot_step(recon, folder, engines=self.engines, device=self.device, video=self.video)
            line = outcome.summary()
        except Exception as exc:  # a messy real scene must not stop the benchmark either
            outcome = RobotOutcome(reason=record_failure(folder, exc, "robot_error.txt"))
            line = f"robot step failed ({outcome.reason})"
        self.cases.append((vid, action, reconstructed, outcome))
        logger.info("%6s %-20s %s", "", "robot", line[:200])
        return outcome.record()

    def skip(self, vid: str, action: str) -> RobotRecord:
        """A video without a reconstruction: every robot column fails."""
        self.cases.append((vid, action, False, None))
        return RobotRecord(False, misses=("no reconstruction",))

    def report(self) -> None:
        """Show the per-video table, the end-to-end count, the timings and how the engines agree."""
        outcomes = [outcome for *_, outcome in self.cases]
        lines = ["", "| video | action | reconstruction | plan | " + " | ".join(f"{e} replay" for e in self.engines) + " |",
                 "| --- | --- | --- | --- | " + " | ".join("---" for _ in self.engines) + " |"]
        for vid, action, reconstructed, outcome in self.cases:
            if outcome is None:
                plan = "no reconstruction"
            elif outcome.planned:
                plan = "found"
            else:
                plan = f"none: {outcome.reason}".replace("|", "/")
            cells = [_verdict(outcome, engine) for engine in self.engines]
            lines.append(f"| {vid} | {action} | {'ok' if reconstructed else 'fail'} | {plan} | " + " | ".join(cells) + " |")
        end = [reconstructed and outcome is not None and outcome.replayed for _, _, reconstructed, outcome in self.cases]
        if end:
            lines.append(f"\nend to end (reconstruction and every replay meet the criteria): {sum(end)}/{len(end)} "
                         f"({100.0 * sum(end) / len(end):.1f} %)")
        lines += timing_lines(outcomes)
        show(*lines, *filter(None, [agreement_line(outcomes)]))


def _verdict(outcome: RobotOutcome | None, engine: str) -> str:
    """A per-video table cell: ``ok``, ``fail (checks)`` or ``-`` (not replayed)."""
    if outcome is None or engine not in outcome.replays:
        return "-"
    return verdict(outcome.success(engine), outcome.failed_checks(engine)).strip()
