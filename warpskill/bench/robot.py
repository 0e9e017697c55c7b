"""``warpskill bench robot``: retarget synthetic reconstructions to the Panda and replay them.

For each action and seed: the reconstruction (the synthetic ground truth, or the optimiser's
output on the noisy demonstration), judged by :func:`warpskill.evaluate`, then the robot step
shared with ``warpskill bench something-else --robot``
(:func:`warpskill.bench.end_to_end.robot_step`): a placo plan and its replay in each engine,
judged by the same criteria, and (robust) once more in MuJoCo under each perturbation a real
robot meets. Shows the success table (reconstruction, planned, replay per engine, robust,
end to end), the planning and replay times (wall and CPU), how the engines agree
(same verdict, distance of the final object positions) and the reason of every failure.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import replace
from pathlib import Path
from typing import Sequence

from warpskill.bench.end_to_end import (
    RobotOutcome,
    agreement,
    agreement_line,
    check_robust_engines,
    robot_rows,
    robot_step,
    timing_lines,
)
from warpskill.bench.report import show
from warpskill.contract.actions import ACTIONS
from warpskill.contract.evaluation import evaluate, success_table
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder
from warpskill.optimizer.options import OptimizeOptions
from warpskill.optimizer.pipeline import optimize
from warpskill.robot import prefer_headless_gl
from warpskill.synthetic import make_demonstration

logger = logging.getLogger(__name__)

SOURCES: tuple[str, ...] = ("truth", "optimised")


def synthetic_reconstruction(action: str, seed: int, source: str, options: OptimizeOptions | None = None, *,
                             noise: str = "moderate", folder: Path | None = None):
    """The reconstruction of synthetic ``action`` / ``seed`` from ``source``.

    ``truth``: the noise-free ground truth, with the demonstration's object noun; ``optimised``:
    :func:`warpskill.optimize` with ``options`` (its seed replaced by ``seed``) on the demonstration with ``noise``, cached
    as ``folder/reconstruction.npz`` when ``folder`` is given (a rerun loads it; a corrupt
    one is redone).
    """

    if source not in SOURCES:
        raise ValueError(f"unknown source {source!r}; valid sources: {', '.join(SOURCES)}")
    if source == "truth":
        demo = make_demonstration(action, seed=seed, noise="none")
        return Reconstruction(**demo.truth, object_noun=demo.object_noun or "")
    keeper = ResultsFolder(folder) if folder is not None else None
    cached = keeper.finished_reconstruction() if keeper is not None else None
    if cached is not None:
        return cached
    recon = optimize(make_demonstration(action, seed=seed, noise=noise), replace(options or OptimizeOptions(), seed=seed),
                     progress=False, checkpoint=keeper.checkpoint if keeper is not None else None)
    if keeper is not None:
        keeper.save(recon, keeper.reconstruction)
    return recon


def bench_robot(options: OptimizeOptions | None = None, *, seeds: int = 3, source: str = "truth",
                engines: Sequence[str] = ("mujoco",), actions: Sequence[str] | None = None, out: Path | None = None,
                video: bool = False, robust: bool = True) -> RobotRun:
    """Plan and replay every action x seed; log each, show the success table per engine and the timings.

    Each case goes through :func:`~warpskill.bench.end_to_end.robot_step`, as the videos of
    ``warpskill bench something-else --robot`` do.

    Args:
        options: the optimiser's options with ``source="optimised"``
            (:class:`OptimizeOptions`; each case with its own seed); its device is also Newton's.
        seeds: seeds per action.
        source: ``truth`` or ``optimised`` (see :func:`synthetic_reconstruction`).
        engines: replay engines (``mujoco``, ``newton``).
        actions: a subset of the actions (default: all 9).
        out: folder for the reconstructions, plans and replays (``OUT/<action>_<seed>/``);
            optimised reconstructions found there are reused.
        video: also write ``OUT/<action>_<seed>/replay.mp4`` of each plan (MuJoCo; a plot
            without an offscreen renderer).
        robust: the ``robust`` row: a plan that succeeds in every engine is replayed in
            MuJoCo under each of :data:`~warpskill.robot.perturbation.PERTURBATIONS` (needs
            ``mujoco`` among the engines).

    Returns:
        The run's :class:`RobotRun`.
    """

    if robust:
        check_robust_engines(engines)
    prefer_headless_gl()
    options = options or OptimizeOptions()
    device = options.device or "cpu"

    actions = list(actions or ACTIONS)
    cases, outcomes, failures = [], [], []
    for action in actions:
        for seed in range(seeds):
            folder = out / f"{action}_{seed}" if out is not None else None
            if folder is not None:
                folder.mkdir(parents=True, exist_ok=True)
            recon = synthetic_reconstruction(action, seed, source, options, folder=folder)
            reconstructed = evaluate(recon, action).success
            outcome = robot_step(recon, folder, engines=engines, device=device, video=video, robust=robust)
            cases.append((action, reconstructed, outcome))
            outcomes.append((action, seed, outcome))
            failures += [f"{action} seed {seed}: {miss}" for miss in outcome.misses()]
            logger.info("%-22s seed %d: %s", action, seed, outcome.summary()[:160])

    rows = robot_rows(cases, engines, robust=robust)
    robots = [outcome for _, _, outcome in outcomes]
    show("", f"reconstructions: {source}", success_table(rows), "", *timing_lines(robots),
         *filter(None, [agreement_line(robots)]))
    if failures:
        show("failures:", *(f"  {line}" for line in failures))
    return RobotRun(rows, outcomes, failures, agreement(robots))


@dataclasses.dataclass(frozen=True)
class RobotRun:
    """What :func:`bench_robot` found.

    Attributes:
        rows: the success table's rows (``reconstruction``, ``planned``, ``replay <engine>``,
            ``robust``, ``end to end``) -> [(action, ok)] per case.
        outcomes: (action, seed, :class:`~warpskill.bench.end_to_end.RobotOutcome`) per case (its
            plan's planning time, its replays' times).
        failures: why each case missed, one line each.
        agreement: how the engines agree (:func:`~warpskill.bench.end_to_end.agreement`).
    """

    rows: dict[str, list[tuple[str, bool]]]
    outcomes: list[tuple[str, int, RobotOutcome]]
    failures: list[str]
    agreement: dict
