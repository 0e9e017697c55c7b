"""``warpskill bench generalize``: does a skill work beyond the one layout it was shown in?

For each reconstruction's skill (:func:`~warpskill.robot.skill_layout.skill_from`), ``layouts``
random layouts of :func:`warpskill.export.layouts.layouts` (the object anywhere on the
Panda's reachable table at any yaw; each static box at a random place and yaw there, apart
from the object, with the object's whole path on the table), each planned
(:func:`warpskill.robot.retarget` with the layout) and replayed in every engine, judged by
the action's criteria on the layout's scene (:func:`~warpskill.bench.end_to_end.robot_step`,
as ``bench robot`` does). A plan that succeeds in every engine is replayed in MuJoCo once
more under each of :data:`~warpskill.robot.perturbation.PERTURBATIONS` (mass x0.5 and x2,
friction -+30 %, the object 1 cm and 5 deg off); it is *robust* when it succeeds under all.

A drawn layout where the skill's relation cannot be met is drawn again before any planning
(out of the Panda's reach, overlapping footprints, no room beside the static box, a release
not beside / behind / in front of / on it as the action's checks judge it: the drawer's
reasons), never judged by a failed replay; the run shows how many draws were redrawn, per
skill and why.

The skill keeps what the object is (the reconstruction's ``object_noun``): an open vessel too
wide for the gripper is held by its rim in every layout, as in the demonstration's replay, and
substituted by a cuboid the gripper fits only where no face or rim does; the run counts, per
skill, the plans that substituted the object and those that held it by its rim.

Shows, per action, planned / succeeded (per engine) / robust as a success table, how the
engines agree, the redrawn layouts, the objects substituted or held by their rims, and the
reason of every miss (the plan's error, the failed checks, the perturbations that broke it). With ``out``, one outcome row per layout (case ``<name>/layout
<k>``, :class:`~warpskill.bench.outcomes.CaseOutcome`: success = replayed in every engine,
its ``robot`` record with the misses and the substitute) goes to ``OUT/outcomes.json``, and the
flips since a baseline table are shown.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections import Counter
from collections.abc import Mapping, Sequence
from itertools import islice
from pathlib import Path

from warpskill.bench.end_to_end import RobotOutcome, agreement_line, check_robust_engines, robot_step
from warpskill.bench.outcomes import CaseOutcome
from warpskill.bench.report import record_outcomes, show
from warpskill.contract.evaluation import success_table
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder
from warpskill.contract.skill import LayoutError
from warpskill.export.layouts import layouts as random_layouts
from warpskill.robot.skill_layout import apply_skill, skill_from

__all__ = ["bench_generalize"]

logger = logging.getLogger(__name__)


def _verdicts(outcome: RobotOutcome, engines: Sequence[str], robust: bool) -> dict[str, bool]:
    """One layout's ``{"planned", "replay <engine>"..., "robust"}`` verdicts (robust only where tried)."""
    verdicts = {"planned": outcome.planned, **{f"replay {engine}": outcome.success(engine) for engine in engines}}
    return {**verdicts, "robust": outcome.robust} if robust else verdicts


def _count(rows: dict, action: str, verdicts: dict[str, bool]) -> None:
    """Add one layout's verdicts to the table's rows."""
    for row, ok in verdicts.items():
        rows.setdefault(row, []).append((action, ok))


def bench_generalize(recons: Mapping[str, Reconstruction], *, layouts: int = 10,
                     engines: Sequence[str] = ("mujoco",), seed: int = 0, device: str = "cpu",
                     robust: bool = True, out: str | os.PathLike | None = None,
                     baseline: str | os.PathLike | None = None,
                     save_baseline: str | os.PathLike | None = None) -> GeneralizeRun:
    """Plan and replay every skill in ``layouts`` random layouts; log each, show the table and the misses.

    Args:
        recons: name -> reconstruction (each with a known action).
        layouts: random layouts per skill.
        engines: replay engines (``mujoco``, ``newton``).
        seed: of the layouts (the i-th reconstruction draws from ``seed + i``).
        device: Warp device of Newton.
        robust: the ``robust`` row: a layout whose plan succeeds in every engine is replayed
            in MuJoCo once more under each perturbation (needs ``mujoco`` among the engines).
        out: folder of the outcome table (None: none written).
        baseline, save_baseline: an earlier run's outcome table (or its folder) to print the
            flips against; where to save a copy of this run's (:func:`~warpskill.bench.report.record_outcomes`).

    Returns:
        The run's :class:`GeneralizeRun`.

    Raises:
        ValueError: ``robust`` without the ``mujoco`` engine.
    """

    if robust:
        check_robust_engines(engines)
    rows: dict[str, list[tuple[str, bool]]] = {}
    misses, outcomes, cases = [], [], []
    redrawn: dict[str, Counter[str]] = {}
    handled: dict[str, Counter[str]] = {}
    nouns: dict[str, str] = {}
    for i, (name, recon) in enumerate(recons.items()):
        skill, done = skill_from(recon), 0
        redrawn[_short(name)] = Counter()
        handled[_short(name)], nouns[_short(name)] = Counter(), skill.object_noun
        try:
            for k, layout in enumerate(islice(random_layouts(skill, seed=seed + i, redrawn=redrawn[_short(name)]),
                                              layouts)):
                outcome = robot_step(apply_skill(skill, layout), engines=engines, device=device, robust=robust,
                                     skill=skill, layout=layout)
                outcomes.append(outcome)
                handled[_short(name)][outcome.handling or ("as it is" if outcome.planned else "no plan")] += 1
                cases.append(_case(f"{_short(name)}/layout {k}", skill.action, outcome))
                verdicts = _verdicts(outcome, engines, robust)
                done += 1
                _count(rows, skill.action, verdicts)
                misses += [f"{name} layout {k} ({layout.describe()}): {reason}" for reason in outcome.misses()]
                logger.info("%s layout %d: %s", name, k, ", ".join(f"{row} {'yes' if ok else 'no'}"
                                                                   for row, ok in verdicts.items()))
        except LayoutError as error:  # no layout fits this skill (e.g. its path runs into the static box)
            unplanned = RobotOutcome(reason=str(error))
            for k in range(done, layouts):
                _count(rows, skill.action, _verdicts(unplanned, engines, robust))
                cases.append(_case(f"{_short(name)}/layout {k}", skill.action, unplanned))
            misses.append(f"{name}: every layout: {error}")
            logger.info("%s: no layout: %s", name, error)
    show("", success_table(rows), *filter(None, [agreement_line(outcomes)]), *_redrawn_lines(redrawn),
         *_handling_lines(handled, nouns))
    if misses:
        show("misses:", *(f"  {line}" for line in misses))
    record_outcomes(out, cases, baseline=baseline, save_baseline=save_baseline)
    return GeneralizeRun(rows, misses, outcomes, cases, redrawn, handled)


def _redrawn_lines(redrawn: Mapping[str, Counter[str]]) -> list[str]:
    """How many draws were refused before planning and drawn again, and why: in all, then per skill."""
    def counts(counter: Counter[str]) -> str:
        reasons = ", ".join(f"{reason} {count}" for reason, count in counter.most_common())
        return f"{counter.total()}" + (f" ({reasons})" if reasons else "")

    total = sum(redrawn.values(), Counter())
    return [f"layouts redrawn before planning: {counts(total)}",
            *(f"  {name}: {counts(counter)}" for name, counter in redrawn.items() if counter)]


def _handling_lines(handled: Mapping[str, Counter[str]], nouns: Mapping[str, str]) -> list[str]:
    """How many plans substituted the object and how many held it by its rim: in all, then per
    skill that did either, with its object's noun."""
    def counts(counter: Counter[str]) -> str:
        return ", ".join(f"{how} {count}" for how, count in counter.most_common())

    total = sum(handled.values(), Counter())
    return [f"objects: substituted in {total['substituted']} plan(s), held by the rim in {total['held by its rim']}",
            *(f"  {name} ({nouns[name] or 'unnamed object'}): {counts(counter)}" for name, counter in handled.items()
              if counter["substituted"] or counter["held by its rim"])]


@dataclasses.dataclass(frozen=True)
class GeneralizeRun:
    """What :func:`bench_generalize` found.

    Attributes:
        rows: the success table's rows (``planned``, ``replay <engine>``, and ``robust`` when
            computed) -> [(action, ok)] per layout.
        misses: why each layout missed, one line each.
        outcomes: the robot step's outcome of each layout that could be laid out.
        cases: each layout's row of the outcome table (:class:`~warpskill.bench.outcomes.CaseOutcome`).
        redrawn: per skill (its name in the outcome table), the draws refused before planning
            and drawn again, counted by reason (:func:`warpskill.export.layouts.layouts`).
        handled: per skill (its name in the outcome table), the
            layouts counted by how the plan held the object (``"substituted"``, ``"held by
            its rim"``, ``"as it is"``) or ``"no plan"``.
    """

    rows: dict[str, list[tuple[str, bool]]]
    misses: list[str]
    outcomes: list[RobotOutcome]
    cases: list[CaseOutcome]
    redrawn: dict[str, Counter[str]]
    handled: dict[str, Counter[str]]


def _short(name: str) -> str:
    """A reconstruction's name in the outcome table: its folder's name for ``.../<case>/reconstruction.npz``."""
    path = Path(name)
    return path.parent.name if path.name == ResultsFolder.RECONSTRUCTION and path.parent.name else path.stem


def _case(case: str, action: str, outcome: RobotOutcome) -> CaseOutcome:
    """One layout's row of the outcome table: success = replayed in every engine; the robot's record."""
    failed = tuple(dict.fromkeys(check for engine in outcome.replays for check in outcome.failed_checks(engine)))
    return CaseOutcome(case, action, outcome.replayed, failed if outcome.planned else ("plan",),
                       note="" if outcome.planned else str(outcome.reason), robot=outcome.record())
