"""Video frames read with OpenCV: a video file, or numbered image files.

:func:`read_video` returns the frames (RGB) and the frame rate the file declares;
:func:`is_image_sequence` tells a printf pattern of numbered images (``frames/%04d.jpg``)
from a video file.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import cv2
import numpy as np

from warpskill.contract.demonstration import DemonstrationError


def is_image_sequence(path: str | os.PathLike) -> bool:
    """Whether ``path`` names numbered frames, a printf pattern such as ``frames/12/%04d.jpg``."""
    return re.search(r"%0?\d*d", Path(path).name) is not None


def read_video(path: str | os.PathLike) -> tuple[np.ndarray, float]:
    """All frames of a video file, or of numbered image files (``frames/%04d.jpg``: see
    :func:`is_image_sequence`; numbering from 0 or 1), read with OpenCV.

    Returns:
        (N, H, W, 3) uint8 RGB frames and the frame rate [1/s] the file declares (0 if none;
        always 0 for image files).

    Raises:
        FileNotFoundError: ``path`` does not exist (for image files: its folder).
        DemonstrationError: OpenCV cannot decode it, or it has no frames.
    """
    sequence = is_image_sequence(path)
    if not (Path(path).parent.is_dir() if sequence else Path(path).is_file()):
        raise FileNotFoundError(f"{path}: no such {'folder of frames' if sequence else 'video file'}")
    frames, fps = _read_images(str(path)) if sequence else _read_video_file(str(path))
    if not frames:
        kind = "no image matches the pattern from 0 or 1 on" if sequence else "not a video, or an unsupported codec"
        raise DemonstrationError(f"{path}: OpenCV read no frames ({kind})")
    return np.stack(frames), fps


def _read_images(pattern: str) -> tuple[list[np.ndarray], float]:
    """RGB frames of numbered image files, from number 0 or 1 to the first number missing."""
    first = 0 if Path(pattern % 0).is_file() else 1
    frames = []
    while Path(pattern % (first + len(frames))).is_file():
        image = cv2.imread(pattern % (first + len(frames)))
        if image is None:
            raise DemonstrationError(f"{pattern % (first + len(frames))}: OpenCV cannot read this image")
        frames.append(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
    return frames, 0.0


def _read_video_file(path: str) -> tuple[list[np.ndarray], float]:
    """RGB frames of a video file and the frame rate it declares (0 if none)."""
    capture = cv2.VideoCapture(path)
    try:
        fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0)
        frames = []
        while True:
            ok, frame = capture.read()
            if not ok:
                break
            frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
    finally:
        capture.release()
    return frames, fps
