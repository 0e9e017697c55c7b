"""``warpskill bench synthetic``: the paper's success table on synthetic demonstrations with ground truth."""

from __future__ import annotations

import dataclasses
import logging
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from warpskill.bench.outcomes import CaseOutcome, action_error_table, camera_frame_errors, judged, verdict
from warpskill.bench.report import record_outcomes, show
from warpskill.contract.actions import ACTIONS
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.evaluation import evaluate, success_table
from warpskill.contract.results_folder import ResultsFolder
from warpskill.nouns.typical import SIZES
from warpskill.optimizer.known import check_known, measured
from warpskill.optimizer.options import OptimizeOptions
from warpskill.optimizer.pipeline import optimize_many
from warpskill.synthetic import check_scenarios, make_demonstration, real_scenarios

logger = logging.getLogger(__name__)

NOUN_SPREAD = 0.3
"""Log-normal spread of real objects' sizes around their noun's typical one (a mug, a
bottle, a box of one name differ by about this much in log)."""


def spread_noun(size: np.ndarray, rng: np.random.Generator, spread: float = NOUN_SPREAD) -> str:
    """A noun of :data:`~warpskill.nouns.typical.SIZES` for an object of edges ``size`` (3,) [m]:
    the one whose typical edges, sorted, are nearest in log to the object's sorted edges times
    one log-normal draw of ``spread``; as for a real object, right only on average."""
    target = np.log(np.sort(size)) + spread * rng.standard_normal()
    return min(SIZES, key=lambda noun: float(np.sum((np.log(SIZES[noun].edges) - target) ** 2)))


def error_table(errors: dict[str, list[dict[str, float]]]) -> str:
    """Median and max over demonstrations of :func:`camera_frame_errors`, one row per method (Markdown;
    a column without a value, such as a static's size where no scene has one, shows "-")."""
    header = ["method", "centre cm", "hand tip cm", "size cm", "static size cm", "release height cm",
              "cam height cm", "elevation deg", "scale", "|scale-1|"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row, errs in errors.items():
        if not errs:
            continue
        col = lambda key, f=1.0: np.array([e[key] for e in errs]) * f  # noqa: E731
        cells = [row]
        for values in (col("centre", 100), col("hand", 100), col("size", 100), col("static_size", 100),
                       col("release_height", 100), col("camera_height", 100), col("elevation", 180 / np.pi)):
            cells.append(f"{np.nanmedian(values):.1f} / {np.nanmax(values):.1f}" if np.isfinite(values).any() else "-")
        scale = col("scale")
        cells.append(f"{np.median(scale):.2f} ({scale.min():.2f}-{scale.max():.2f})")
        off = np.abs(scale - 1)
        cells.append(f"{np.median(off):.2f} / {off.max():.2f}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n(median / max over demonstrations; scale: reconstructed / true distance of the object from the camera)"


def bench_synthetic(
    options: OptimizeOptions | None = None,
    *,
    seeds: int = 3,
    noise: str = "moderate",
    actions: Sequence[str] | None = None,
    out: Path | None = None,
    input: str = "masks",
    known: Sequence[str] = (),
    seed_start: int = 0,
    scenarios: str = "none",
    baseline: Path | None = None,
    save_baseline: Path | None = None,
    nouns: bool = False,
) -> SyntheticRun:
    """Reconstruct synthetic demonstrations of each action, log each, show the paper's table.

    Rows: initialisation only, and the full method; columns: the actions (k/n), total, %.
    Also shows the ground-truth errors (:func:`error_table`) and the time per
    demonstration.

    Args:
        options: the optimisation options (:class:`OptimizeOptions`); each case runs with
            its own seed, once with ``init_only`` and once without (the two rows).
        input: ``"masks"`` or ``"boxes"`` (see :func:`warpskill.synthetic.make_demonstration`).
        known: names of lengths (:data:`warpskill.optimizer.known.KNOWN_LENGTHS`) given to
            the optimiser at each scene's true values, e.g. ``["object_height"]``
            (``known_each`` of :func:`~warpskill.optimizer.optimize_many`).
        seed_start: the first seed (seeds ``seed_start .. seed_start + seeds - 1``).
        scenarios: ``"real"`` mixes the real videos' situations into ``"boxes"`` demonstrations,
            ``"narrow"`` makes put actions' static boxes narrower than the object, ``"turned"``
            turns them by up to 30 deg (see
            :func:`warpskill.synthetic.make_demonstration`).
        baseline, save_baseline: see :func:`warpskill.bench.report.record_outcomes`; the
            full method's per-case outcomes are also written to ``out`` (``outcomes.json``).
        nouns: give each demonstration an ``object_noun`` whose typical size is its object's
            times a log-normal spread (:func:`spread_noun`), named in the case's note.

    Returns:
        The run's :class:`SyntheticRun`.
    """
    check_known({name: 1.0 for name in known})
    options = options or OptimizeOptions()

    actions = list(actions or ACTIONS)
    check_scenarios(scenarios, input, actions)
    rows: dict[str, list] = {"initialisation only": [], "full method": []}
    errors: dict[str, list] = {"initialisation only": [], "full method": []}
    seconds = []
    outcomes = []
    with tempfile.TemporaryDirectory() as scratch:
        for action in actions:
            for seed in range(seed_start, seed_start + seeds):
                demo, note = _case(action, seed, noise=noise, input=input, scenarios=scenarios, nouns=nouns)
                given = _known_lengths(demo, known)
                folder = ResultsFolder((out or Path(scratch)) / f"{action}_{seed}")
                folder.path.mkdir(parents=True, exist_ok=True)
                checkpoint = folder.checkpoint
                start = time.perf_counter()
                for row, init_only in (("initialisation only", True), ("full method", False)):
                    [recon] = optimize_many([demo], replace(options, seed=seed, init_only=init_only),
                                            known_each=[given], progress=False, checkpoint=checkpoint)
                    evaluation = evaluate(recon, action)
                    ok = evaluation.success
                    rows[row].append((action, ok))
                    errors[row].append(camera_frame_errors(recon, demo.truth))
                    if out is not None:
                        folder.save(recon, folder.initialisation if init_only else folder.reconstruction)
                seconds.append(time.perf_counter() - start)
                outcome = judged(f"{action}_{seed}", recon, evaluation, errors["full method"][-1])
                outcomes.append(replace(outcome, note=note))
                if out is not None:
                    folder.save(demo, folder.demonstration)
                logger.info("%-22s seed %d: init %s full %s  %6.1f s", action, seed,
                            verdict(rows["initialisation only"][-1][1]), verdict(rows["full method"][-1][1]), seconds[-1])

    show("", success_table(rows), "", error_table(errors), "", action_error_table(outcomes),
         f"time per demonstration (both stages, {options.device or 'cpu'}): median {statistics.median(seconds):.1f} s, "
         f"max {max(seconds):.1f} s")
    record_outcomes(out, outcomes, baseline=baseline, save_baseline=save_baseline)
    return SyntheticRun(rows, errors, seconds, outcomes)


@dataclasses.dataclass(frozen=True)
class SyntheticRun:
    """What :func:`bench_synthetic` found.

    Attributes:
        rows: the success table's rows (``initialisation only``, ``full method``) -> [(action, success)].
        errors: the same rows -> each case's :func:`camera_frame_errors`, in case order.
        seconds: each case's time [s], both stages.
        outcomes: the full method's :class:`~warpskill.bench.outcomes.CaseOutcome` of each case.
    """

    rows: dict[str, list[tuple[str, bool]]]
    errors: dict[str, list[dict[str, float]]]
    seconds: list[float]
    outcomes: list[CaseOutcome]


def _case(action: str, seed: int, *, noise: str, input: str, scenarios: str, nouns: bool) -> tuple[Demonstration, str]:
    """A case's demonstration (with a spread noun, :func:`spread_noun`, where ``nouns``) and its note:
    the real videos' situations mixed in (``scenarios="real"``) and the noun."""
    demo = make_demonstration(action, seed=seed, noise=noise, input=input, scenarios=scenarios)
    if nouns:
        rng = np.random.default_rng([seed, ACTIONS.index(action)])
        demo = replace(demo, object_noun=spread_noun(demo.truth["object_size"], rng))
    situations = " ".join(real_scenarios(action, seed)) if scenarios == "real" else ""
    return demo, " ".join(filter(None, [situations, nouns and f"noun={demo.object_noun}"]))


def _known_lengths(demo: Demonstration, known: Sequence[str]) -> dict[str, float]:
    """The lengths named in ``known`` at the demonstration's true values [m] (those it has)."""
    t = {k: torch.as_tensor(np.asarray(demo.truth[k], dtype=np.float64))
         for k in ("object_size", "static_size", "camera_height")}
    given = {}
    for name in known:
        value = measured(name, t["object_size"], t["static_size"], t["camera_height"])
        if value is not None:
            given[name] = float(value)
    return given
