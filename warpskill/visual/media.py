"""Writing frames as a video file (MP4 through OpenCV, GIF through imageio) and figures as PNG (Agg, no pyplot)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import imageio.v3 as iio
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

if TYPE_CHECKING:
    pass



VIDEO_FORMATS = ("gif", "mp4")


def write_video(path: Path, frames: np.ndarray, fps: float) -> Path:
    """Write RGB ``frames`` (N, H, W, 3) as a looping GIF or an MP4 at ``fps`` frames/s."""
    if path.suffix == ".gif":
        iio.imwrite(path, frames, extension=".gif", duration=1000.0 / fps, loop=0)
        return path
    H, W = frames.shape[1:3]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (W, H))
    if not writer.isOpened():
        raise OSError(f"{path}: OpenCV cannot write MP4 video here; use frames_video='gif'")
    try:
        for frame in frames:
            writer.write(frame[..., ::-1])
    finally:
        writer.release()
    return path


def figure(width: float, height: float) -> Figure:
    """A figure of ``width`` x ``height`` inches with constrained layout, drawn by Agg.

    Built without pyplot: no global backend switch, no display, nothing left open.
    """
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path: Path) -> Path:
    """Save ``fig`` as a PNG at 120 dpi."""
    fig.savefig(path, dpi=120)
    return path
