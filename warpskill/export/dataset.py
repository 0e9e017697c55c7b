"""``warpskill export lerobot``: successful rollouts of reconstructed skills as one LeRobot dataset.

For each reconstruction, random layouts are tried (:func:`~warpskill.export.rollouts.rollouts`)
until ``episodes`` succeed or ``episodes * ATTEMPTS_PER_EPISODE`` have been tried; every
success becomes an episode of the dataset (:class:`~warpskill.export.lerobot.LeRobotWriter`).
A contact sheet ``OUT/contact_sheet.png`` shows a few episodes' frames side by side.
"""

from __future__ import annotations

import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from tqdm import tqdm

from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.skill import skill_from
from warpskill.export.lerobot import LeRobotWriter
from warpskill.export.rollouts import CAMERAS, STATE_NAMES, Episode, rollouts

__all__ = ["ATTEMPTS_PER_EPISODE", "export_lerobot"]

ATTEMPTS_PER_EPISODE = 4  # layouts tried per wanted episode before giving up on a reconstruction
SHEET_EPISODES = 4  # episodes on the contact sheet (rows) ...
SHEET_FRAMES = 6  # ... and frames of each (columns)


def export_lerobot(out: Path, recon_paths: list[Path], *, episodes: int, fps: int | None = None,
                   size: int = 128, cameras: list[str] = ("front", "top"), seed: int = 0,
                   progress: bool = True) -> dict:
    """Write ``episodes`` successful rollouts per reconstruction as a LeRobot v3.0 dataset in ``out``.

    Args:
        out: the dataset folder (empty or absent).
        recon_paths: ``reconstruction.npz`` files, each with a known action.
        episodes: successful rollouts wanted per reconstruction.
        fps: the dataset's frame rate [1/s]; default: the first reconstruction's, rounded.
        size: camera frames are ``size`` x ``size`` px (even).
        cameras: names from :data:`~warpskill.export.rollouts.CAMERAS`.
        seed: of the layouts (reconstruction i draws from ``seed + i``).
        progress: show a progress bar.

    Returns:
        ``{"episodes": {path: count}, "attempts": {path: count}, "misses": [str], "seconds": float,
        "cpu_seconds": float}``.

    Raises:
        ValueError: an unknown camera, a bad count or size, a reconstruction without an action.
    """
    unknown = sorted(set(cameras) - set(CAMERAS))
    if unknown or episodes < 1 or size < 2 or size % 2:
        raise ValueError(f"export lerobot: need episodes >= 1, an even size and cameras from {sorted(CAMERAS)}; "
                         f"got {episodes}, {size}, {list(cameras)}")
    recons = [Reconstruction.load(path) for path in recon_paths]
    fps = fps or max(1, round(float(recons[0].fps)))
    started, cpu = time.perf_counter(), time.process_time()
    summary = {"episodes": {}, "attempts": {}, "misses": []}
    shown: list[Episode] = []
    writer = LeRobotWriter(out, fps=fps, vectors={"observation.state": STATE_NAMES, "action": STATE_NAMES},
                           cameras={f"observation.images.{name}": (size, size) for name in cameras})
    with writer, tqdm(total=episodes * len(recons), unit="episode", disable=not progress) as bar:
        for i, (path, recon) in enumerate(zip(recon_paths, recons)):
            done = tried = 0
            attempts = rollouts(skill_from(recon), fps=fps, cameras=[CAMERAS[name] for name in cameras],
                                size=(size, size), seed=seed + i)
            while done < episodes and tried < episodes * ATTEMPTS_PER_EPISODE:
                attempt = next(attempts)
                tried += 1
                if attempt.episode is None:
                    summary["misses"].append(f"{path}: {attempt.layout.describe()}: {attempt.reason}")
                    continue
                episode = attempt.episode
                writer.add_episode({"observation.state": episode.state, "action": episode.action},
                                   {f"observation.images.{name}": frames for name, frames in episode.frames.items()},
                                   episode.task)
                shown += [episode] if len(shown) < SHEET_EPISODES else []
                done += 1
                bar.update(1)
            summary["episodes"][str(path)], summary["attempts"][str(path)] = done, tried
            if done < episodes:
                print(f"{path}: only {done} of {episodes} rollouts succeeded in {tried} layouts", flush=True)
    if shown:
        contact_sheet(shown, cameras[0], Path(out) / "contact_sheet.png")
    summary.update(seconds=time.perf_counter() - started, cpu_seconds=time.process_time() - cpu)
    return summary


def contact_sheet(episodes: list[Episode], camera: str, path: Path) -> Path:
    """A PNG of :data:`SHEET_FRAMES` evenly spaced frames (columns) of each episode (rows) from ``camera``."""
    rows = []
    for episode in episodes:
        frames = episode.frames[camera]
        picks = np.linspace(0, len(frames) - 1, SHEET_FRAMES).round().astype(int)
        rows.append(np.concatenate(list(frames[picks]), axis=1))
    iio.imwrite(path, np.concatenate(rows, axis=0))
    return path
