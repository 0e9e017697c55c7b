"""The page's files on disk: the uploaded clip, one folder per run, the results' zip.

Everything the page writes lives under its root folder (``warpskill app -o ROOT``)::

    ROOT/<clip>-<n>/clip.mp4 or frames/0000.png ...   the clip as uploaded
    ROOT/<clip>-<n>/run-<m>/                          one ``warpskill run`` results folder
                                                      (docs/formats.md) and outline.json
    ROOT/<clip>-<n>/run-<m>.zip                       that folder, to download
"""

from __future__ import annotations

import functools
import os
import shutil
from pathlib import Path

import cv2
import numpy as np

from warpskill.contract import DemonstrationError
from warpskill.data import read_video

__all__ = ["FRAMES_FPS", "clip_folder", "clip_frames", "new_folder", "store_clip", "zip_folder"]

FRAMES_FPS = 12.0
"""Frame rate [1/s] of a clip uploaded as images (``warpskill run``'s default for numbered frames)."""

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".webp")
"""Uploaded files read as frames; any other file is a video."""


def new_folder(parent: Path, stem: str) -> Path:
    """Create and return ``parent/<stem>-<n>``, n the first number not taken (1, 2, ...)."""
    parent.mkdir(parents=True, exist_ok=True)
    for number in range(1, 100_000):
        folder = parent / f"{stem}-{number}"
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        return folder
    raise FileExistsError(f"{parent}: no free folder name for {stem}")


def store_clip(uploads: list[str | os.PathLike], root: Path) -> Path:
    """Copy an uploaded clip into a new folder under ``root``.

    Args:
        uploads: one video file, or several images (the frames, in the order of their names).
        root: the page's folder.

    Returns:
        What ``warpskill run`` reads: the video's copy, or ``frames/%04d.png``.

    Raises:
        DemonstrationError: no file, one image alone, or a mix of a video and other files.
    """
    paths = sorted((Path(p) for p in uploads), key=lambda p: p.name)
    images = [p for p in paths if p.suffix.lower() in IMAGE_SUFFIXES]
    if not paths:
        raise DemonstrationError("no clip: upload a video file or its frames (several images)")
    if len(paths) == 1 and not images:
        folder = new_folder(root, _stem(paths[0]))
        clip = folder / f"clip{paths[0].suffix.lower()}"
        shutil.copyfile(paths[0], clip)
        return clip
    if len(images) != len(paths) or len(images) < 2:
        raise DemonstrationError("a clip is one video file or several images (its frames), "
                                 f"got {', '.join(p.name for p in paths)}")
    frames = new_folder(root, _stem(paths[0])) / "frames"
    frames.mkdir()
    for index, path in enumerate(images):
        image = cv2.imread(str(path))
        if image is None:
            raise DemonstrationError(f"{path.name}: not an image OpenCV reads")
        cv2.imwrite(str(frames / f"{index:04d}.png"), image)
    return frames / "%04d.png"


def clip_folder(clip: Path) -> Path:
    """The folder :func:`store_clip` made for ``clip`` (where its runs go)."""
    return clip.parent.parent if "%" in clip.name else clip.parent


@functools.lru_cache(maxsize=2)
def _read(clip: str, modified: int) -> tuple[np.ndarray, float]:
    frames, fps = read_video(clip)
    frames.setflags(write=False)
    return frames, fps


def clip_frames(clip: Path) -> tuple[np.ndarray, float]:
    """The clip's (T, H, W, 3) uint8 RGB frames (read-only, read once) and its frame rate
    [1/s] (:data:`FRAMES_FPS` for images)."""
    stamp = clip.parent if "%" in clip.name else clip
    frames, fps = _read(str(clip), stamp.stat().st_mtime_ns)
    return frames, fps or FRAMES_FPS


def zip_folder(folder: Path) -> Path:
    """Write ``folder`` as ``<folder>.zip`` beside it (the folder's name its top directory); return the zip."""
    return Path(shutil.make_archive(str(folder), "zip", root_dir=folder.parent, base_dir=folder.name))


def _stem(path: Path) -> str:
    """A folder name from the upload's file name: letters, digits, ``-`` and ``_``."""
    stem = "".join(c if c.isalnum() or c in "-_" else "_" for c in path.stem)[:40]
    return stem or "clip"
