"""Writing pictures and videos, and the colour of each role in them: a leaf every layer may import.

- :func:`write_mp4`: H.264 video (libx264, yuv420p, moov atom first) that browsers,
  notebooks and Rerun's video asset play; :func:`write_gif`: a looping GIF;
  :func:`write_video` picks one by the file's suffix.
- :func:`figure` / :func:`save_figure`: a matplotlib figure drawn by Agg (no pyplot) and
  its PNG.
- The palette: one RGB colour (0-255) per role (hand, object, static objects, robot),
  shared by the overlay, the plots, the Rerun recording (:mod:`warpskill.visual`) and the
  robot's replay video (:mod:`warpskill.robot.video`). It lives here, not in either of them,
  because robot and visual never import each other.

Imports no other warpskill module (``pyproject.toml``'s import contracts).
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import av
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

__all__ = [
    "GRIPPER_COLOR",
    "HAND_COLOR",
    "HAND_HELD_COLOR",
    "OBJECT_COLOR",
    "REPLAY_OBJECT_COLOR",
    "ROBOT_COLOR",
    "STATIC_COLOR",
    "TRUTH_COLOR",
    "VIDEO_FORMATS",
    "figure",
    "rgb",
    "save_figure",
    "write_gif",
    "write_mp4",
    "write_video",
]

HAND_COLOR = (255, 140, 20)
"""The hand (orange); in the 3D recording the hand while free."""

HAND_HELD_COLOR = (139, 26, 0)
"""The hand while it holds the object (dark red; the 3D recording blends towards it with ``grasped``)."""

OBJECT_COLOR = (40, 200, 70)
"""The manipulated object (green)."""

STATIC_COLOR = (40, 110, 255)
"""The static objects (blue)."""

ROBOT_COLOR = (225, 225, 230)
"""The Panda's arm links (light grey)."""

GRIPPER_COLOR = (60, 60, 65)
"""The Panda's hand and fingers (dark grey)."""

REPLAY_OBJECT_COLOR = (230, 60, 200)
"""The object as the robot replay simulated it, where shown beside the reconstructed one (magenta)."""

TRUTH_COLOR = (255, 255, 255)
"""The ground truth of a synthetic demonstration (white)."""

VIDEO_FORMATS = ("gif", "mp4")
"""The suffixes :func:`write_video` writes."""

MP4_CODEC = "libx264"
"""The H.264 encoder of :func:`write_mp4`."""

MP4_QUALITY = "20"
"""libx264's constant rate factor: 0 lossless ... 51 worst; about 20 is visually clean."""


def rgb(color: tuple[int, ...]) -> tuple[float, ...]:
    """An 8-bit colour as floats in [0, 1] (matplotlib's form)."""
    return tuple(c / 255.0 for c in color)


def write_video(path: Path, frames: np.ndarray, fps: float) -> Path:
    """Write RGB ``frames`` (T, H, W, 3) uint8 at ``fps`` [1/s] as ``.mp4`` (:func:`write_mp4`) or ``.gif``.

    Raises:
        ValueError: another suffix, or frames of another shape or type.
    """
    path = Path(path)
    if path.suffix == ".mp4":
        return write_mp4(path, frames, fps)
    if path.suffix == ".gif":
        return write_gif(path, frames, fps)
    raise ValueError(f"{path}: expected a .mp4 or .gif file name (formats {VIDEO_FORMATS})")


def write_gif(path: Path, frames: np.ndarray, fps: float) -> Path:
    """Write RGB ``frames`` (T, H, W, 3) uint8 as a GIF that loops, shown at ``fps`` [1/s].

    Each frame's 256 colours are chosen by Pillow's fast octree (about twenty times faster
    than its default median cut on a 640 x 480 frame, as faithful to the eye)."""
    frames = _checked_frames(frames, fps)
    images = [Image.fromarray(frame).quantize(method=Image.Quantize.FASTOCTREE) for frame in frames]
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:], duration=1000.0 / fps, loop=0)
    return Path(path)


def write_mp4(path: Path, frames: np.ndarray, fps: float) -> Path:
    """Write RGB ``frames`` (T, H, W, 3) uint8 as an H.264 MP4 at ``fps`` [1/s].

    Encoded by libx264 in yuv420p (what browsers, notebooks and Rerun decode), with the
    index at the front of the file (``faststart``: plays while loading). yuv420p needs even
    sizes: an odd height or width is padded by repeating the last row or column.

    Raises:
        ValueError: frames not (T, H, W, 3) uint8 with T >= 1, or ``fps`` not positive.
    """
    frames = _even_sized(_checked_frames(frames, fps))
    rate = Fraction(fps).limit_denominator(1001)
    with av.open(str(path), mode="w", options={"movflags": "faststart"}) as container:
        stream = container.add_stream(MP4_CODEC, rate=rate)
        stream.height, stream.width = frames.shape[1:3]
        stream.pix_fmt = "yuv420p"
        stream.options = {"crf": MP4_QUALITY}
        for frame in frames:
            container.mux(stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")))
        container.mux(stream.encode())  # flush the encoder's delayed frames
    return Path(path)


def _checked_frames(frames: np.ndarray, fps: float) -> np.ndarray:
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or len(frames) == 0 or frames.dtype != np.uint8:
        raise ValueError(f"frames: expected (T, H, W, 3) uint8 with T >= 1, got {frames.shape} {frames.dtype}")
    if not fps > 0:
        raise ValueError(f"fps: expected a positive frame rate, got {fps}")
    return np.ascontiguousarray(frames)


def _even_sized(frames: np.ndarray) -> np.ndarray:
    """``frames`` with an odd height or width padded by one edge row or column."""
    pad_h, pad_w = frames.shape[1] % 2, frames.shape[2] % 2
    if not (pad_h or pad_w):
        return frames
    return np.pad(frames, ((0, 0), (0, pad_h), (0, pad_w), (0, 0)), mode="edge")


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
    return Path(path)
