"""Per-case outcome tables of the success benchmarks, and the cases that flipped since a baseline.

Every success benchmark (``bench synthetic``, ``bench something-else``, ``bench
second-opinion``) writes ``OUT/outcomes.json`` and ``OUT/outcomes.csv``: one row per case
(a synthetic ``<action>_<seed>``, a video id) with its action, whether the reconstruction
met the criteria, the checks it failed, each check's margin (how far it was from flipping [m],
:func:`~warpskill.contract.evaluation.evaluate`; the smallest, the case's closest call, in the
CSV and the per-case lines) and its key errors against the ground truth where there is one.
A baseline is such a table, or any output folder of these benchmarks: a folder without
``outcomes.json`` (written by older code) is re-evaluated from the ``<case>/reconstruction.npz``
files in it, so that earlier runs count as baselines too; a table of older code has no margins.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import operator
import os
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.evaluation import Evaluation, closest_call, evaluate
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder
from warpskill.engine.projection import world_to_camera
from warpskill.geometry import cuboid_corners, release_frame

NOTES = "notes.txt"
"""A case's file of what was done about messy annotations, one note a line."""
OUTCOMES_JSON = "outcomes.json"
OUTCOMES_CSV = "outcomes.csv"
ERROR_KEYS = ("centre", "hand", "size", "static_size", "release_height", "camera_height", "elevation", "scale",
              "noun_ratio", "hand_ratio")
"""Key errors kept per case, where defined (see :func:`camera_frame_errors`; on real videos ``noun_ratio``: the
object's largest edge over its noun's typical one, ``hand_ratio``: over the hand's measure of it,
:func:`~warpskill.bench.rulers.hand_ruler_ratio`)."""


def verdict(ok: bool, failed_checks: Sequence[str] | None = None) -> str:
    """A printed verdict: ``ok  `` or ``fail``, the failed checks in brackets where given."""
    if ok:
        return "ok  "
    return "fail" if failed_checks is None else "fail (" + ", ".join(failed_checks) + ")"


@dataclasses.dataclass(frozen=True)
class RobotRecord:
    """The robot step of one case, as the outcome table keeps it
    (:meth:`~warpskill.bench.end_to_end.RobotOutcome.record`).

    Attributes:
        planned: whether a Panda plan was found.
        replays: engine -> whether its replay achieved the action, in the order run.
        robust: whether it also succeeded under every perturbation; None where not tried.
        misses: why it missed, one line each (empty: it succeeded everywhere it was tried).
        substitute: the plan's note on the object the robot handles instead, or empty.
    """

    planned: bool
    replays: dict[str, bool] = dataclasses.field(default_factory=dict)
    robust: bool | None = None
    misses: tuple[str, ...] = ()
    substitute: str = ""

    @property
    def success(self) -> bool:
        """Planned, every replay and (where tried) every perturbed one succeeded."""
        return bool(self.planned and self.replays and all(self.replays.values()) and self.robust is not False)

    @classmethod
    def from_json(cls, row: dict | None) -> RobotRecord | None:
        """The record of an outcome table's ``robot`` cell; None for none (``null``, or the ``{}`` of
        older tables)."""
        return cls(**dict(row, misses=tuple(row["misses"]))) if row else None


@dataclasses.dataclass(frozen=True)
class CaseOutcome:
    """How one case of a benchmark ended.

    Attributes:
        case: the case id (``<action>_<seed>``, a video id).
        action: the action name.
        success: whether the reconstruction met the criteria.
        failed_checks: the criteria it failed (``error`` when there was no reconstruction).
        errors: key errors against the ground truth ([m], [rad], scale), empty without one.
        note: why there is no reconstruction, or empty.
        robot: the robot step where it ran (:class:`RobotRecord`), else None.
        margins: check name -> its signed margin [m] (positive: passed with that much room);
            empty without a reconstruction, and in tables of older code.
        hypotheses: the simulated hypotheses its reconstruction was chosen from, with their
            fits (the reconstruction's ``hypotheses`` record, docs/formats.md); empty without
            one, and in tables of older code.
    """

    case: str
    action: str
    success: bool
    failed_checks: tuple[str, ...] = ()
    errors: dict[str, float] = dataclasses.field(default_factory=dict)
    note: str = ""
    robot: RobotRecord | None = None
    margins: dict[str, float] = dataclasses.field(default_factory=dict)
    hypotheses: list[dict] = dataclasses.field(default_factory=list)

    def closest_call(self) -> tuple[str, float] | None:
        """The check nearest to flipping and its margin [m] (negative: the case failed); None
        without margins."""
        return closest_call(self.margins)

    def choice_gap(self) -> tuple[str, str, float] | None:
        """How close its reconstruction came to ending on the static box's other side: the
        chosen hypothesis's start, the start of the best-fitting one the masks allow that ends
        on the other side (behind the static against not), and how much worse that one fits,
        as a share of the chosen's fit; None where no such rival was simulated."""
        kept = next((h for h in self.hypotheses if h["chosen"]), None)
        if kept is None or kept["ends_behind_static"] is None:
            return None
        rivals = [h for h in self.hypotheses if not h["contradicted"]
                  and h["ends_behind_static"] is not None and h["ends_behind_static"] != kept["ends_behind_static"]]
        if not rivals:
            return None
        rival = min(rivals, key=lambda h: h["fit"])
        return kept["start"], rival["start"], (rival["fit"] - kept["fit"]) / max(kept["fit"], 1e-9)

    def closest_text(self) -> str:
        """The closest call in words, ``behind_static +0.012 m``; empty without margins."""
        closest = self.closest_call()
        return "" if closest is None else f"{closest[0]} {closest[1]:+.3f} m"

    @property
    def robot_success(self) -> bool | None:
        """Whether the robot achieved the action (:attr:`RobotRecord.success`); None where the robot
        step did not run."""
        return None if self.robot is None else self.robot.success

    def verdict(self) -> str:
        """The printed verdict: ``ok  `` or ``fail (`` the failed checks ``)``."""
        return verdict(self.success, self.failed_checks)

    def to_json(self) -> dict:
        """The outcome as a row of ``outcomes.json``."""
        return dict(dataclasses.asdict(self), failed_checks=list(self.failed_checks),
                    robot=None if self.robot is None else dict(dataclasses.asdict(self.robot),
                                                               misses=list(self.robot.misses)))

    @classmethod
    def from_json(cls, row: dict) -> CaseOutcome:
        """An outcome from a row of ``outcomes.json``, this code's or older code's."""
        return cls(**dict(row, failed_checks=tuple(row["failed_checks"]), robot=RobotRecord.from_json(row.get("robot"))))


def judged(case: str, recon: Reconstruction, evaluation: Evaluation,
           errors: dict[str, float] | None = None) -> CaseOutcome:
    """The outcome of a case from its reconstruction's evaluation (and its ground-truth errors, if any)."""
    failed = tuple(name for name, ok in evaluation.checks.items() if not ok)
    kept = {key: float(errors[key]) for key in ERROR_KEYS if errors and key in errors and np.isfinite(errors[key])}
    return CaseOutcome(case, evaluation.action, evaluation.success, failed, kept, margins=dict(evaluation.margins),
                       hypotheses=recon.judgements())


def failed_case(case: str, action: str, reason: str) -> CaseOutcome:
    """The outcome of a case that has no reconstruction (it counts as a failure)."""
    return CaseOutcome(case, action, False, ("error",), {}, reason)


def write_notes(folder: Path, notes: list[str]) -> None:
    """Write a case's notes to ``folder/notes.txt`` (atomically, creating the folder)."""
    ResultsFolder(folder).write_text(folder / NOTES, "".join(note + "\n" for note in notes))


class CaseFailed(Exception):
    """A case that failed elsewhere (a Ray task), its reason already recorded there."""


def record_failure(folder: Path, error: BaseException, error_file: str | None = None) -> str:
    """The one-line reason of a case's ``error``, its traceback kept in ``folder``'s error file
    (or ``folder/error_file``) where the folder exists (call from the ``except`` block); a
    :class:`CaseFailed` is its reason as it is, recorded where it failed."""
    if isinstance(error, CaseFailed):
        return str(error)
    if folder.exists():
        keeper = ResultsFolder(folder)
        keeper.write_text(folder / error_file if error_file else keeper.error, traceback.format_exc())
    return f"{type(error).__name__}: {one_line(error)}"


def one_line(error: BaseException) -> str:
    """An error as one line: its message with every run of whitespace (newlines too) made one space."""
    return " ".join(str(error).split()) or type(error).__name__


def write_outcomes(folder: str | os.PathLike, outcomes: list[CaseOutcome]) -> Path:
    """Write ``outcomes.json`` and ``outcomes.csv`` into ``folder``; returns the JSON's path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / OUTCOMES_JSON
    save_outcomes(path, outcomes)
    with open(folder / OUTCOMES_CSV, "w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(["case", "action", "success", "failed_checks", "closest_check", "closest_margin", *ERROR_KEYS,
                         "note", "robot", "robot_misses"])
        for o in outcomes:
            cells = [f"{o.errors[key]:.4f}" if key in o.errors else "" for key in ERROR_KEYS]
            closest = o.closest_call()
            closest = ["", ""] if closest is None else [closest[0], f"{closest[1]:.4f}"]
            robot = "" if o.robot_success is None else int(o.robot_success)
            writer.writerow([o.case, o.action, int(o.success), " ".join(o.failed_checks), *closest, *cells, o.note,
                             robot, "; ".join(o.robot.misses if o.robot else ())])
    return path


def save_outcomes(path: str | os.PathLike, outcomes: list[CaseOutcome]) -> None:
    """Write an outcome table as JSON (``{"cases": [...]}``) to ``path``."""
    rows = [o.to_json() for o in outcomes]
    Path(path).write_text(json.dumps({"cases": rows}, indent=1) + "\n")


def load_outcomes(source: str | os.PathLike) -> dict[str, CaseOutcome]:
    """Case id -> outcome, from an outcome JSON or a benchmark's output folder.

    A folder with ``outcomes.json`` gives that table; one without is re-evaluated from its
    ``<case>/reconstruction.npz`` files (:func:`evaluate_folder`).

    Raises:
        FileNotFoundError: ``source`` does not exist.
        ValueError: a JSON file that is not an outcome table, or a folder with neither.
    """
    source = Path(source)
    if not source.exists():
        raise FileNotFoundError(f"baseline {source}: no such file or folder")
    if source.is_dir():
        if (source / OUTCOMES_JSON).exists():
            return load_outcomes(source / OUTCOMES_JSON)
        outcomes = evaluate_folder(source)
        if not outcomes:
            raise ValueError(f"baseline {source}: neither {OUTCOMES_JSON} nor <case>/reconstruction.npz in it")
        return {o.case: o for o in outcomes}
    try:
        rows = json.loads(source.read_text())["cases"]
        outcomes = [CaseOutcome.from_json(row) for row in rows]
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise ValueError(f"baseline {source}: not an outcome table ({type(exc).__name__}: {exc})") from None
    return {o.case: o for o in outcomes}


def evaluate_folder(folder: str | os.PathLike) -> list[CaseOutcome]:
    """Outcomes of the reconstructions in a benchmark's output folder, evaluated now.

    Each ``folder/<case>/reconstruction.npz`` is judged by :func:`evaluate_case` for its own
    action (stored in it, else the ``<action>_<seed>`` case name's). Cases without a
    reconstruction are left out.
    """
    paths = Path(folder).glob(f"*/{ResultsFolder.RECONSTRUCTION}")
    cases = sorted((path.parent for path in paths), key=lambda case: (len(case.name), case.name))
    return [evaluate_case(case) for case in cases]


def folder_outcomes(out: str | os.PathLike, actions: dict[str, str], failures: dict[str, str]) -> list[CaseOutcome]:
    """Outcomes of the cases ``actions`` (case id -> action) of a run into ``out``: a failure
    (``failures``: case id -> reason) or the evaluation of ``out/<case>/reconstruction.npz``."""
    outcomes = []
    for case, action in actions.items():
        if case in failures or not (Path(out) / case / ResultsFolder.RECONSTRUCTION).exists():
            outcomes.append(failed_case(case, action, failures.get(case, "no reconstruction")))
        else:
            outcomes.append(evaluate_case(Path(out) / case, action))
    return outcomes


def evaluate_case(folder: Path, action: str | None = None) -> CaseOutcome:
    """The outcome of ``folder/reconstruction.npz`` for ``action`` (default: the one stored in it,
    else the ``<action>_<seed>`` folder name's); a ``demonstration.npz`` with ground truth
    beside it adds the errors."""
    recon = Reconstruction.load(folder / ResultsFolder.RECONSTRUCTION)
    evaluation = evaluate(recon, action or str(recon.action) or folder.name.rsplit("_", 1)[0])
    errors = None
    demo_path = folder / ResultsFolder.DEMONSTRATION
    if demo_path.exists():
        truth = Demonstration.load(demo_path).truth
        errors = camera_frame_errors(recon, truth) if truth else None
    return judged(folder.name, recon, evaluation, errors)


def camera_frame_errors(recon, truth: dict[str, np.ndarray]) -> dict[str, float]:
    """Errors of a reconstruction against the ground truth.

    Keys: ``centre`` and ``hand`` (median over frames of the object-centre and hand-tip
    error [m], in each scene's own camera frame, where the world's ambiguity (camera height
    and elevation) cancels); ``size`` (sorted edge lengths, mean absolute error [m]: a
    cuboid's axes may be permuted); ``camera_height`` [m] and ``elevation`` [rad] (absolute
    errors); ``scale``: the scene's size relative to the truth, the median over frames of
    the object centre's distance from the camera, reconstructed over true (scaling the
    scene about the camera multiplies exactly this distance); ``static_size`` (the first
    static's sorted edges, mean absolute error [m]; NaN without a static) and
    ``release_height`` (the height [m] of the object's lowest corner above the table where
    each lets it go, :func:`~warpskill.geometry.release_frame`: on a static's top, on the
    table, or in the air; absolute error).
    """

    def in_camera(pos, height, elevation):
        p = torch.as_tensor(np.asarray(pos, dtype=np.float64))
        return world_to_camera(p, torch.tensor(float(height), dtype=torch.float64),
                               torch.tensor(float(elevation), dtype=torch.float64)).numpy()

    est = in_camera(recon.object_pos, recon.camera_height, recon.camera_elevation)
    ref = in_camera(truth["object_pos"], truth["camera_height"], truth["camera_elevation"])
    hand_est = in_camera(recon.hand_pos, recon.camera_height, recon.camera_elevation)
    hand_ref = in_camera(truth["hand_pos"], truth["camera_height"], truth["camera_elevation"])
    size_error = np.abs(np.sort(recon.object_size) - np.sort(truth["object_size"])).mean()
    static_error = (float(np.abs(np.sort(recon.static_size[0]) - np.sort(truth["static_size"][0])).mean())
                    if len(recon.static_size) and len(truth["static_size"]) else float("nan"))
    return {
        "centre": float(np.median(np.linalg.norm(est - ref, axis=1))),
        "hand": float(np.median(np.linalg.norm(hand_est - hand_ref, axis=1))),
        "size": float(size_error),
        "camera_height": float(abs(float(recon.camera_height) - float(truth["camera_height"]))),
        "elevation": float(abs(float(recon.camera_elevation) - float(truth["camera_elevation"]))),
        "scale": float(np.median(np.linalg.norm(est, axis=1) / np.linalg.norm(ref, axis=1))),
        "static_size": static_error,
        "release_height": abs(_release_height(recon.grasped, recon.object_pos, recon.object_rot, recon.object_size)
                              - _release_height(truth["grasped"], truth["object_pos"], truth["object_rot"],
                                                truth["object_size"])),
    }


def _release_height(grasped, object_pos, object_rot, object_size) -> float:
    """[m] the height of the object's lowest corner where the hand lets it go (grasped (N,),
    object poses (N, 3) and (N, 3, 3), edges (3,))."""
    k = release_frame(np.asarray(grasped))
    corners = cuboid_corners(np.asarray(object_pos)[k], np.asarray(object_rot)[k], np.asarray(object_size))
    return float(corners[..., 2].min())


def flips(baseline: dict[str, CaseOutcome], current: dict[str, CaseOutcome],
          verdict: Callable[[CaseOutcome], bool | None] = operator.attrgetter("success")) -> tuple[list, list]:
    """The cases in both tables whose ``verdict`` (default: the reconstruction's success; None:
    not judged, skipped) changed: (fixed, broken), each a list of (baseline outcome, current
    outcome) pairs in case order."""
    fixed, broken = [], []
    for case, now in current.items():
        before = baseline.get(case)
        if before is None or None in (verdict(before), verdict(now)) or verdict(before) == verdict(now):
            continue
        (fixed if verdict(now) else broken).append((before, now))
    return fixed, broken


def flip_report(baseline: dict[str, CaseOutcome], current: dict[str, CaseOutcome], name: str = "baseline") -> str:
    """Lines naming every case that flipped since ``baseline``, both ways, with the failed checks and
    their margins before and now (where the tables have them); then the robot step's flips where
    both tables have it, with its misses."""
    lines = _flip_lines(f"since {name}", baseline, current, operator.attrgetter("success"),
                        lambda o: f"failing {_checks(o)}", _margin_change)
    lines += _flip_lines("robot step", baseline, current, operator.attrgetter("robot_success"),
                         lambda o: f"missing: {'; '.join(o.robot.misses)}", optional=True)
    shared = set(baseline) & set(current)
    only_now, only_before = sorted(set(current) - shared), sorted(set(baseline) - shared)
    if only_now:
        lines.append(f"  not in {name}: {_listed(only_now)}")
    if only_before:
        lines.append(f"  only in {name}: {_listed(only_before)}")
    return "\n".join(lines)


def _flip_lines(title: str, baseline: dict[str, CaseOutcome], current: dict[str, CaseOutcome],
                verdict: Callable[[CaseOutcome], bool | None], why: Callable[[CaseOutcome], str],
                change: Callable[[CaseOutcome, CaseOutcome], str] = lambda before, now: "", *,
                optional: bool = False) -> list[str]:
    """One ``verdict``'s part of :func:`flip_report`: the count over the cases both tables judge, then
    each flip with ``why`` it fails and ``change(before, now)``; nothing where ``optional`` and no case
    is judged in both."""
    both = [c for c in set(baseline) & set(current) if None not in (verdict(baseline[c]), verdict(current[c]))]
    if optional and not both:
        return []
    fixed, broken = flips(baseline, current, verdict)
    lines = [f"{title}: {len(both)} case(s) in both, {sum(verdict(baseline[c]) for c in both)} -> "
             f"{sum(verdict(current[c]) for c in both)} succeed; {len(fixed)} fixed, {len(broken)} broken"]
    lines += [f"  fixed  {now.case:<24} {now.action:<20} was {why(before)}{change(before, now)}"
              for before, now in fixed]
    return lines + [f"  broken {now.case:<24} {now.action:<20} now {why(now)}{change(before, now)}"
                    for before, now in broken]


def _margin_change(before: CaseOutcome, now: CaseOutcome) -> str:
    """``; behind_static +0.010 -> -0.004 m``: the margins [m] of the checks failed before or now
    (``?``: a table without them); empty when neither table has margins."""
    if not before.margins and not now.margins:
        return ""
    names = dict.fromkeys(name for name in (*before.failed_checks, *now.failed_checks)
                          if name in before.margins or name in now.margins)
    return "".join(f"; {name} {_signed(before.margins.get(name))} -> {_signed(now.margins.get(name))} m"
                   for name in names)


def _signed(margin: float | None) -> str:
    return "?" if margin is None else f"{margin:+.3f}"


def close_calls(outcomes: list[CaseOutcome], most: int = 5) -> str:
    """The ``most`` cases nearest to flipping (smallest margin in size, either way), one line; empty
    without margins."""
    nearest = sorted((o for o in outcomes if o.margins), key=lambda o: abs(o.closest_call()[1]))[:most]
    calls = [f"{o.case} ({'ok' if o.success else 'fail'}) {o.closest_text()}" for o in nearest]
    return f"closest calls: {', '.join(calls)}" if calls else ""


def close_choices(outcomes: list[CaseOutcome], most: int = 5) -> str:
    """The ``most`` cases whose reconstruction chose between ending behind the static box and
    not by the narrowest fit (:meth:`CaseOutcome.choice_gap`), one line; empty where none did."""
    gaps = sorted(((o, gap) for o in outcomes if (gap := o.choice_gap()) is not None), key=lambda pair: pair[1][2])
    choices = [f"{o.case} ({'ok' if o.success else 'fail'}) {kept} over {rival} by {100 * gap:.0f} %"
               for o, (kept, rival, gap) in gaps[:most]]
    return f"closest choices (the other side of the static fitting worse by): {', '.join(choices)}" if choices else ""


def _listed(cases: list[str], most: int = 10) -> str:
    """Up to ``most`` case ids, then how many more."""
    more = f" and {len(cases) - most} more" if len(cases) > most else ""
    return ", ".join(cases[:most]) + more


def median_errors(outcomes: list[CaseOutcome]) -> dict[str, float]:
    """Median of each key error over the cases that have it."""
    return {key: float(np.median([o.errors[key] for o in outcomes if key in o.errors]))
            for key in ERROR_KEYS if any(key in o.errors for o in outcomes)}


def action_error_table(outcomes: Sequence[CaseOutcome]) -> str:
    """Per action: the cases that succeed, and the median object-centre, static-size and
    release-height errors [cm] over its cases that have them (Markdown; "-": none has it)."""
    lines = ["| action | succeed | centre cm | static size cm | release height cm |", "|---|---|---|---|---|"]
    for action in dict.fromkeys(o.action for o in outcomes):
        cases = [o for o in outcomes if o.action == action]
        cells = [action, f"{sum(bool(o.success) for o in cases)}/{len(cases)}"]
        for key in ("centre", "static_size", "release_height"):
            values = [o.errors[key] for o in cases if key in o.errors]
            cells.append(f"{100 * np.median(values):.1f}" if values else "-")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _checks(outcome: CaseOutcome) -> str:
    text = "(" + ", ".join(outcome.failed_checks) + ")"
    return text + (f": {outcome.note}" if outcome.note else "")
