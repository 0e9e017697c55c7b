"""``warpskill bench second-opinion``: the real-video path on an independent generator's scenes.

The shared tools ``synthdemo.py`` (scripted scenes with ground truth, written without
regard to warpskill) and ``synth_sthelse.py`` (their masks as Something-Else box
annotations and phases) are run as separate programs: into ``OUT/demos`` and
``OUT/annotations``. The annotation files then go through the real reader
(:func:`~warpskill.data.boxes.something_else.read_something_else`,
:func:`~warpskill.data.boxes.something_else.something_else_demonstration`), exactly as a real
video's (:func:`~warpskill.bench.cases.run_case`), are reconstructed into
``OUT/<action>_s<seed>/`` and judged by the success criteria and against the generator's
ground truth. The tools' folder is a setting (``tools``, else ``$WARPSKILL_TOOLS``:
:func:`~warpskill.bench.settings.data_folder`); without it the benchmark says so and stops.
"""

from __future__ import annotations

import csv
import functools
import logging
import os
import subprocess
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from warpskill.bench.outcomes import CaseOutcome, median_errors
from warpskill.bench.report import record_outcomes, show
from warpskill.bench.cases import reconstruct_here, run_case
from warpskill.bench.settings import TOOLS_VARIABLE, SettingError, data_folder
from warpskill.contract.actions import ACTIONS
from warpskill.contract.demonstration import TRUTH_PREFIX
from warpskill.contract.evaluation import success_table
from warpskill.data.boxes.something_else import read_something_else
from warpskill.optimizer.options import OptimizeOptions

logger = logging.getLogger(__name__)

GENERATOR = "synthdemo.py"
ANNOTATOR = "synth_sthelse.py"
ROW = "full method (second-opinion boxes)"


def find_tools(tools: str | os.PathLike | None = None) -> Path | None:
    """The folder holding both tools: ``tools`` when given, else ``$WARPSKILL_TOOLS``; None when
    that folder lacks them.

    Raises:
        SettingError: neither is given, or the folder does not exist.
    """
    folder = data_folder(tools, TOOLS_VARIABLE, "--tools", f"folder of {GENERATOR} and {ANNOTATOR}")
    return folder if (folder / GENERATOR).is_file() and (folder / ANNOTATOR).is_file() else None


def generate_annotations(tools: Path, out: Path, actions: Sequence[str], seeds: Sequence[int], *,
                         noise: int = 0, exit_view: bool = False) -> Path:
    """Run the two tools: demonstrations into ``out/demos``, annotation files into
    ``out/annotations`` (returned). Existing files are regenerated (the tools are deterministic)."""
    demos, annotations = out / "demos", out / "annotations"
    command = [sys.executable, str(tools / GENERATOR), str(demos), "--actions", ",".join(actions),
               "--seeds", *map(str, seeds), "--noise", str(noise), "--quiet"]
    subprocess.run(command + (["--exit-view"] if exit_view else []), check=True)
    paths = [str(demos / f"{action}_s{seed}.npz") for action in actions for seed in seeds]
    subprocess.run([sys.executable, str(tools / ANNOTATOR), *paths, str(annotations)], check=True,
                   stdout=subprocess.DEVNULL)
    return annotations


def read_truth(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """The ``truth_*`` arrays of a generated demonstration, keyed without the prefix."""
    with np.load(path, allow_pickle=False) as arrays:
        return {key[len(TRUTH_PREFIX):]: arrays[key] for key in arrays.files if key.startswith(TRUTH_PREFIX)}


def bench_second_opinion(
    out: str | os.PathLike,
    options: OptimizeOptions | None = None,
    *,
    seeds: Sequence[int] = range(1, 11),
    actions: Sequence[str] | None = None,
    exit_view: bool = False,
    noise: int = 0,
    tools: str | os.PathLike | None = None,
    baseline: str | os.PathLike | None = None,
    save_baseline: str | os.PathLike | None = None,
) -> list[CaseOutcome] | None:
    """Generate, annotate, read, reconstruct and judge; log each case, show the table and the errors.

    Args:
        out: output folder (``demos/``, ``annotations/``, ``<action>_s<seed>/``, the outcome table).
        seeds: the generator's seeds.
        actions: a subset of the actions (default: all 9).
        exit_view: pick-ups lifted out of the top of the view (the generator's ``--exit-view``).
        options: the optimisation options (:class:`OptimizeOptions`); default: all defaults.
        noise: the generator's mask and contact noise level (0, 1, 2).
        tools: the folder of the tools (default: see :func:`find_tools`).
        baseline: an outcome table or output folder to report flips against.
        save_baseline: also save the outcome table here.

    Returns:
        The :class:`~warpskill.bench.outcomes.CaseOutcome` of each scene, or None when the tools
        are absent.
    """

    try:
        folder = find_tools(tools)
    except SettingError as error:
        logger.warning("second opinion skipped: %s", error)
        return None
    if folder is None:
        where = tools or f"${TOOLS_VARIABLE}"
        logger.warning("second opinion skipped: %s and %s not found in %s", GENERATOR, ANNOTATOR, where)
        return None
    out = Path(out)
    actions = list(actions or ACTIONS)
    annotations = generate_annotations(folder, out, actions, seeds, noise=noise, exit_view=exit_view)
    table = read_something_else(annotations / "annotations.json", annotations / "phases.csv",
                                annotations / "actions.csv")
    demo_paths = _ids(annotations / "ids.csv")
    options = options or OptimizeOptions()
    outcomes: list[CaseOutcome] = []
    for vid, video in table.items():  # as bench something-else runs a video, judged against the truth too
        case = out / Path(demo_paths[vid]).stem
        made = functools.partial(reconstruct_here, video, case, options, False, {})
        outcomes.append(run_case(case.name, video.action, case, made, truth=functools.partial(read_truth, demo_paths[vid])))
    rows = {ROW: [(o.action, o.success) for o in outcomes]}
    show("", success_table(rows))
    medians = median_errors(outcomes)
    if medians:
        show("median errors: " + ", ".join(f"{key} {value:.3f}" for key, value in medians.items()))
    record_outcomes(out, outcomes, baseline=baseline, save_baseline=save_baseline)
    return outcomes


def _ids(path: Path) -> dict[str, str]:
    """video id -> the generated demonstration's path (the annotator's ``ids.csv``)."""
    with open(path, newline="") as handle:
        return {row["video_id"]: row["demo"] for row in csv.DictReader(handle)}
