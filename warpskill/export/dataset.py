"""``warpskill export lerobot``: rollouts of reconstructed skills as one LeRobot dataset, never half-written.

For each reconstruction (a *skill*), random layouts are drawn and judged by a MuJoCo replay
(:func:`~warpskill.export.rollouts.rollouts`) until ``episodes`` succeed or the skill's budget
of ``episodes * attempts_per_episode`` layouts is spent; a refused layout or a failed replay is
one more draw, never an error. A skill with fewer successes, or none that fits the table, is
left out with its reason. The chosen layouts are then filmed (every camera, offscreen) and
written as episodes (:class:`~warpskill.export.lerobot.LeRobotWriter`) with their labels
(``next.success``, ``next.done``, ``next.reward``), the tool centre point's pose, each camera's
calibration and, in ``meta/warpskill.json``, where every skill came from.

The dataset is built in a temporary folder beside ``OUT`` (``.OUT.partial-<pid>-*``) and
renamed to ``OUT`` only when complete: a failed or interrupted export leaves ``OUT`` as it was
(a killed one leaves its temporary folder, which the next export beside it removes).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from tqdm import tqdm

import warpskill
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.evaluation import evaluate
from warpskill.contract.reconstruction import Reconstruction, ReconstructionError
from warpskill.contract.skill import LayoutError, Skill, SkillError
from warpskill.export.lerobot import CODEBASE_VERSION, LeRobotWriter
from warpskill.export.rollouts import (
    CAMERAS,
    EE_POSE_NAMES,
    ENGINE,
    STATE_NAMES,
    TASKS,
    Attempt,
    Episode,
    film_attempt,
    rollouts,
)
from warpskill.progress import progress_bar
from warpskill.robot.skill_layout import skill_from

__all__ = ["ATTEMPTS_PER_EPISODE", "EXPORT_VERSION", "PROVENANCE", "ExportError", "ExportRequest", "ExportSummary",
           "SkillOutcome", "export_lerobot"]

ATTEMPTS_PER_EPISODE = 4  # layouts planned and replayed per wanted episode: a skill's budget
EXPORT_VERSION = 2  # of what warpskill adds to the LeRobot format: labels, ee pose, calibration, provenance
PROVENANCE = "meta/warpskill.json"  # where each skill came from (lerobot ignores the file)
PERTURBATION = "none"  # the episodes' simulated world is the nominal one (warpskill.robot.perturbation)
SHEET_EPISODES = 4  # episodes on the contact sheet (rows) ...
SHEET_FRAMES = 6  # ... and frames of each (columns)

FEATURE_INFO = {
    "observation.state": {
        "units": ["rad"] * 7 + ["m"],
        "description": "absolute joint positions of the simulated Panda arm and its gripper opening (the distance "
                       "between the fingers, 0 closed to 0.08 m open)"},
    "observation.ee_pose": {
        "units": ["m"] * 3 + ["1"] * 4,
        "description": "the simulated tool centre point (between the finger pads, +z the approach direction) in the "
                       "robot base frame (x forward, z up): position and unit quaternion in the order w, x, y, z, "
                       "its sign continuous within an episode and w >= 0 on its first frame"},
    "action": {
        "units": ["rad"] * 7 + ["m"],
        "description": "absolute joint-position targets of the arm's position actuators and the commanded gripper "
                       "opening [m] at the frame's time (joint space, not deltas, not end effector)"},
    "next.reward": {"description": "1 on the last frame of a successful episode, else 0"},
    "next.done": {"description": "true on the last frame of every episode"},
    "next.success": {"description": "true on the last frame of an episode whose replay achieved the action (the "
                                    "action's criteria judge the whole rollout), else false"},
}
"""Units and conventions of the features, added to their entries in ``meta/info.json``."""


class ExportError(ValueError):
    """A request that cannot be exported (bad options, an unreadable reconstruction, ``OUT`` not empty)."""


@dataclasses.dataclass(frozen=True)
class ExportRequest:
    """What to export.

    Attributes:
        episodes: successful rollouts wanted per skill.
        fps: the dataset's frame rate [1/s]; None: the first reconstruction's, rounded.
        image_size: (width, height) [px] of every camera's frames, even.
        cameras: names from :data:`~warpskill.export.rollouts.CAMERAS`.
        seed: of the layouts (skill i draws from ``seed + i``); the same seed gives the same dataset.
        keep_failures: also write the failed replays of the chosen attempts, labelled.
        attempts_per_episode: a skill's budget is ``episodes`` times this many layouts planned and replayed.
    """

    episodes: int
    fps: int | None = None
    image_size: tuple[int, int] = (128, 128)
    cameras: tuple[str, ...] = ("front", "top")
    seed: int = 0
    keep_failures: bool = False
    attempts_per_episode: int = ATTEMPTS_PER_EPISODE

    def check(self) -> None:
        """Raise :class:`ExportError` naming the first bad option."""
        unknown = sorted(set(self.cameras) - set(CAMERAS))
        if unknown or not self.cameras or len(set(self.cameras)) != len(self.cameras):
            raise ExportError(f"cameras: expected distinct names from {', '.join(CAMERAS)}, got {list(self.cameras)}")
        width, height = self.image_size
        if min(width, height) < 2 or width % 2 or height % 2:
            raise ExportError(f"image size: expected even WIDTH HEIGHT >= 2 px (H.264), got {width} x {height}")
        if self.episodes < 1 or self.attempts_per_episode < 1:
            raise ExportError(f"episodes: expected at least 1 (and 1 attempt per episode), got {self.episodes}")
        if self.fps is not None and self.fps < 1:
            raise ExportError(f"fps: expected a positive integer, got {self.fps}")

    def to_json(self) -> dict:
        """The request as JSON-ready values."""
        return {**dataclasses.asdict(self), "image_size": list(self.image_size), "cameras": list(self.cameras)}


@dataclasses.dataclass
class Source:
    """One reconstruction to export and where it came from.

    Attributes:
        path: the reconstruction file.
        name: the skill's name: its results folder's (the video id for ``bench something-else``
            folders) where the file is ``reconstruction.npz``, else the file's stem.
        recon: the reconstruction.
        sha256: of the reconstruction file.
        demonstration: the ``demonstration.npz`` beside it (path, SHA-256, action, object noun), or None.
    """

    path: Path
    name: str
    recon: Reconstruction
    sha256: str
    demonstration: dict | None

    @property
    def object_noun(self) -> str | None:
        """The object's noun: the reconstruction's, else the demonstration's, else the options', else None."""
        if str(self.recon.object_noun):
            return str(self.recon.object_noun)
        if self.demonstration and self.demonstration["object_noun"]:
            return self.demonstration["object_noun"]
        return self.options.get("object_noun") if self.options else None

    @property
    def options(self) -> dict | None:
        """The reconstruction's optimisation options (``OptimizeOptions`` JSON), None if not recorded."""
        return json.loads(str(self.recon.options)) if str(self.recon.options) else None

    def skill(self) -> Skill:
        """The reconstruction's skill, its object named by :attr:`object_noun` (an older
        reconstruction without the noun takes the demonstration's: an open vessel is held by its rim).

        Raises:
            SkillError: no skill in the reconstruction (:func:`~warpskill.robot.skill_layout.skill_from`).
        """
        return dataclasses.replace(skill_from(self.recon), object_noun=self.object_noun or "")


@dataclasses.dataclass
class SkillOutcome:
    """What one skill gave.

    Attributes:
        name, path, action: the skill (see :class:`Source`).
        episodes: dataset indices of its successful episodes.
        failures: dataset indices of its failed episodes (``keep_failures``).
        attempts: layouts planned and replayed.
        misses: each failed attempt's reason.
        left_out: why the skill gave no episode ("" if it gave its episodes).
        note: a remark on the source (its reconstruction failing its own checks).
    """

    name: str
    path: Path
    action: str
    episodes: list[int] = dataclasses.field(default_factory=list)
    failures: list[int] = dataclasses.field(default_factory=list)
    attempts: int = 0
    misses: list[str] = dataclasses.field(default_factory=list)
    left_out: str = ""
    note: str = ""

    def line(self) -> str:
        """One line: the episodes it gave from how many layouts, or why it was left out."""
        head = f"{self.name} ({self.action})"
        if self.left_out:
            return f"{head}: left out: {self.left_out}"
        kept = f", {len(self.failures)} failures kept" if self.failures else ""
        note = f"; {self.note}" if self.note else ""
        return f"{head}: {len(self.episodes)} episodes from {self.attempts} layouts{kept}{note}"


@dataclasses.dataclass
class ExportSummary:
    """The export: ``out`` holds the dataset when ``episodes`` > 0, else nothing was written."""

    out: Path
    skills: list[SkillOutcome]
    seconds: float = 0.0
    cpu_seconds: float = 0.0

    @property
    def episodes(self) -> int:
        """Successful episodes written."""
        return sum(len(skill.episodes) for skill in self.skills)


def export_lerobot(out: Path, recon_paths: list[Path], request: ExportRequest, *, progress: bool = True,
                   ) -> ExportSummary:
    """Write ``request.episodes`` successful rollouts per skill as a LeRobot v3.0 dataset in ``out``.

    Nothing is written when no skill gives an episode, and ``out`` is left as it was by any
    error or interruption (see the module doc).

    Raises:
        ExportError: a bad option, no or an unreadable reconstruction, ``out`` a file or a folder that is not empty.
    """
    request.check()
    out = Path(out)
    sources = load_sources(recon_paths)
    _check_out(out)
    started, cpu = time.perf_counter(), time.process_time()
    staging = _Staging(out)
    try:
        summary = _write(staging.root, sources, request, progress)
        if summary.episodes:
            staging.publish()
    finally:
        staging.discard()
    summary.out = out
    summary.seconds, summary.cpu_seconds = time.perf_counter() - started, time.process_time() - cpu
    return summary


def load_sources(paths: list[Path]) -> list[Source]:
    """The reconstructions with their provenance.

    Raises:
        ExportError: no path, or a file that is missing or breaks the format.
    """
    if not paths:
        raise ExportError("no reconstruction given: pass one or more reconstruction.npz files")
    sources = []
    for path in map(Path, paths):
        try:
            recon = Reconstruction.load(path)
        except (OSError, ReconstructionError) as error:
            raise ExportError(f"{path}: not a readable reconstruction ({error})") from None
        name = path.parent.name if path.name == "reconstruction.npz" else path.stem
        sources.append(Source(path, name or path.stem, recon, _sha256(path), _demonstration(path.parent)))
    return sources


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _demonstration(folder: Path) -> dict | None:
    """Path, SHA-256, action and object noun of ``folder/demonstration.npz``, or None where there is none."""
    path = folder / "demonstration.npz"
    if not path.is_file():
        return None
    try:
        demo = Demonstration.load(path)
    except (OSError, ValueError) as error:
        return {"path": str(path), "sha256": _sha256(path), "error": str(error), "action": None, "object_noun": None}
    return {"path": str(path), "sha256": _sha256(path), "action": demo.action, "object_noun": demo.object_noun}


def _check_out(out: Path) -> None:
    if out.exists() and not (out.is_dir() and not any(out.iterdir())):
        raise ExportError(f"{out}: the dataset folder must be absent or empty")
    if not out.parent.is_dir():
        raise ExportError(f"{out.parent}: no such folder to write the dataset in")


class _Staging:
    """A fresh folder beside ``out`` where the dataset is built; :meth:`publish` renames it to ``out``.

    Leftovers of killed exports beside ``out`` (their process gone) are removed on creation.
    """

    def __init__(self, out: Path):
        self.out = out
        prefix = f".{out.name}.partial-"
        for stale in out.parent.glob(prefix + "*"):
            if not _alive(stale.name[len(prefix):].split("-")[0]):
                shutil.rmtree(stale, ignore_errors=True)
        self.root = Path(tempfile.mkdtemp(prefix=f"{prefix}{os.getpid()}-", dir=out.parent))
        umask = os.umask(0)
        os.umask(umask)
        self.root.chmod(0o777 & ~umask)  # as a folder made by mkdir (mkdtemp's is private)

    def publish(self) -> None:
        """Move the finished dataset to ``out`` (an empty ``out`` is replaced)."""
        if self.out.is_dir():
            self.out.rmdir()
        os.rename(self.root, self.out)

    def discard(self) -> None:
        """Remove the temporary folder (nothing left after :meth:`publish`)."""
        shutil.rmtree(self.root, ignore_errors=True)


def _alive(pid: str) -> bool:
    """Whether process ``pid`` (digits) still runs; False for anything else."""
    try:
        os.kill(int(pid), 0)
    except (ValueError, ProcessLookupError):
        return False
    except PermissionError:
        return True
    return True


def _write(root: Path, sources: list[Source], request: ExportRequest, progress: bool) -> ExportSummary:
    """Judge every skill's layouts, film and write the chosen ones into ``root``; the metadata if any episode."""
    fps = request.fps or max(1, round(float(sources[0].recon.fps)))
    width, height = request.image_size
    writer = LeRobotWriter(
        root, fps=fps, vectors={"observation.state": STATE_NAMES, "observation.ee_pose": EE_POSE_NAMES,
                                "action": STATE_NAMES},
        scalars={"next.reward": "float32", "next.done": "bool", "next.success": "bool"},
        cameras={f"observation.images.{name}": (height, width) for name in request.cameras},
        feature_info=FEATURE_INFO,
        info={"cameras": {f"observation.images.{name}": CAMERAS[name].calibration(width, height).to_json()
                          for name in request.cameras}})
    summary, shown = ExportSummary(root, []), []
    try:
        with progress_bar(total=request.episodes * len(sources), unit="episode", enabled=progress) as bar:
            for i, source in enumerate(sources):
                outcome, chosen = _judge_skill(source, request, request.seed + i)
                for attempt_index, tried in chosen:
                    episode = film_attempt(tried, TASKS[outcome.action], fps=fps,
                                           cameras=[CAMERAS[name] for name in request.cameras], size=(height, width))
                    index = _add_episode(writer, episode, source.name, attempt_index)
                    (outcome.episodes if episode.success else outcome.failures).append(index)
                    shown += [episode] if episode.success and len(shown) < SHEET_EPISODES else []
                    bar.update(int(episode.success))
                summary.skills.append(outcome)
                if progress:
                    tqdm.write(outcome.line())
    except BaseException:
        writer.abort()
        raise
    if not summary.episodes:
        writer.abort()
        return summary
    writer.close()
    _write_provenance(root / PROVENANCE, sources, summary, request, fps)
    contact_sheet(shown, request.cameras[0], root / "contact_sheet.png")
    return summary


def _judge_skill(source: Source, request: ExportRequest, seed: int) -> tuple[SkillOutcome, list[tuple[int, Attempt]]]:
    """Draw and judge layouts of one skill within its budget.

    Returns:
        its outcome (``left_out`` set where it falls short) and the attempts to film with their
        numbers: the ``episodes`` successes and, with ``keep_failures``, the replayed failures
        among the attempts made; none where the skill is left out.
    """
    outcome = SkillOutcome(source.name, source.path, str(source.recon.action) or "unknown")
    outcome.note = _reconstruction_note(source.recon)
    budget = request.episodes * request.attempts_per_episode
    tried: list[Attempt] = []
    try:
        attempts = rollouts(source.skill(), seed=seed)
        while sum(a.success for a in tried) < request.episodes and len(tried) < budget:
            tried.append(next(attempts))
    except (SkillError, LayoutError) as error:  # no skill in it, or no layout of it fits the table
        outcome.left_out = str(error)
    outcome.attempts = len(tried)
    outcome.misses = [f"layout {k} ({a.layout.describe()}): {a.reason}" for k, a in enumerate(tried) if a.reason]
    successes = sum(a.success for a in tried)
    if not outcome.left_out and successes < request.episodes:
        outcome.left_out = (f"{successes} of {request.episodes} wanted layouts succeeded within its budget of "
                            f"{budget} ({_commonest([a.reason for a in tried if a.reason])})")
    if outcome.left_out:
        return outcome, []
    return outcome, [(k, a) for k, a in enumerate(tried) if a.success or (request.keep_failures and a.plan is not None)]


def _reconstruction_note(recon: Reconstruction) -> str:
    """"" where the reconstruction achieves its action, else which of its checks fail."""
    if not str(recon.action):
        return ""
    failed = [name for name, ok in evaluate(recon, str(recon.action)).checks.items() if not ok]
    return f"its reconstruction fails {', '.join(failed)}" if failed else ""


def _commonest(reasons: list[str]) -> str:
    """The commonest kind of failure among attempts' ``reasons`` (``plan``, ``replay``, ``replay fails ...``)."""
    kinds = [reason.split(":")[0] for reason in reasons]
    if not kinds:
        return "no failure"
    kind = max(sorted(set(kinds)), key=kinds.count)
    return f"{kinds.count(kind)} x {kind}"


def _add_episode(writer: LeRobotWriter, episode: Episode, skill: str, attempt_index: int) -> int:
    """Write ``episode`` with its labels and episode columns; returns its index."""
    length = len(episode.state)
    last = np.arange(length) == length - 1
    layout = {"object": list(episode.layout.object), "statics": [list(pose) for pose in episode.layout.statics]}
    return writer.add_episode(
        {"observation.state": episode.state, "observation.ee_pose": episode.ee_pose, "action": episode.action},
        {f"observation.images.{name}": frames for name, frames in episode.frames.items()}, episode.task,
        scalars={"next.reward": (last & episode.success).astype(np.float32), "next.done": last,
                 "next.success": last & episode.success},
        columns={"skill": skill, "attempt": attempt_index, "success": episode.success, "failure": episode.reason,
                 "layout": json.dumps(layout), "engine": ENGINE, "perturbation": PERTURBATION})


def _write_provenance(path: Path, sources: list[Source], summary: ExportSummary, request: ExportRequest,
                      fps: int) -> None:
    """``meta/warpskill.json``: the format versions, the request and, per skill, its source and outcome."""
    skills = []
    for source, outcome in zip(sources, summary.skills):
        skills.append({
            "name": source.name, "action": outcome.action, "task": TASKS.get(outcome.action),
            "object_noun": source.object_noun,
            "reconstruction": {"path": str(source.path), "sha256": source.sha256, "note": outcome.note},
            "demonstration": source.demonstration, "options": source.options,
            "episodes": outcome.episodes, "failures": outcome.failures, "attempts": outcome.attempts,
            "left_out": outcome.left_out, "misses": outcome.misses})
    provenance = {"format": {"lerobot": CODEBASE_VERSION, "warpskill_export": EXPORT_VERSION},
                  "warpskill_version": warpskill.__version__, "engine": ENGINE, "perturbation": PERTURBATION,
                  "fps": fps, "request": request.to_json(), "skills": skills}
    path.write_text(json.dumps(provenance, indent=2))


def contact_sheet(episodes: list[Episode], camera: str, path: Path) -> Path:
    """A PNG of :data:`SHEET_FRAMES` evenly spaced frames (columns) of each episode (rows) from ``camera``."""
    rows = []
    for episode in episodes:
        frames = episode.frames[camera]
        picks = np.linspace(0, len(frames) - 1, SHEET_FRAMES).round().astype(int)
        rows.append(np.concatenate(list(frames[picks]), axis=1))
    iio.imwrite(path, np.concatenate(rows, axis=0))
    return path
