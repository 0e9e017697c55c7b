"""Pictures of a reconstruction, to judge it by eye.

:func:`save_pictures` writes three files into a folder:

- ``overlay.gif``: every frame, the reconstruction ray cast into the camera
  (:func:`warpskill.engine.raycast.raycast_masks`) as translucent colours (hand orange, object
  green, static objects blue) over the demonstration's masks in shades of grey (or over
  video frames), with the frame index, time, contact flag and grasp state in a corner.
  Grey without colour is mask the reconstruction misses; colour over the dark background
  is reconstruction the masks do not support.
- ``top_view.png``: a bird's-eye view of the ground plane (x right, y away from the
  camera): static footprints, the object's footprint at the first and last frame and its
  centre path, the hand tip path coloured by the grasp state, and the camera.
- ``trajectories.png``: hand tip and object centre coordinates, the grasp signal g and
  ``grasped`` over time, contact frames shaded, ground truth dashed when the
  demonstration has it.

Units: metres, seconds, radians (``docs/formats.md``); images are H x W pixels, RGB uint8.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.media import VIDEO_FORMATS, save_figure, write_video
from warpskill.visual.overlay import (
    check_picture_inputs,
    check_render_scale,
    overlay_frames,
)
from warpskill.visual.plots import top_view_figure, trajectories_figure

"""RGB of the reconstructed hand (orange)."""

"""RGB of the reconstructed manipulated object (green)."""

"""RGB of the reconstructed static objects (blue)."""

"""Opacity of the reconstruction's fill in the overlay; its outline is opaque."""

"""Grey level of each demonstration mask (and of the empty background) in the overlay."""

"""Overlays of narrower images are enlarged by a whole factor to at least this width [px]."""

"""Most pixels (frames x H x W) ray cast for one overlay; larger videos render smaller."""


def save_pictures(
    recon: Reconstruction,
    demo: Demonstration | None,
    out_dir: str | os.PathLike,
    *,
    background: np.ndarray | None = None,
    frames_video: str | None = "gif",
    render_scale: float | None = None,
) -> dict[str, Path]:
    """Write the overlay video, the top view and the trajectory plots of ``recon``.

    Args:
        recon: the reconstruction to draw.
        demo: the demonstration it was fitted to (masks, contact, ground truth), or None
            to draw the reconstruction alone.
        out_dir: folder to write into; created if missing.
        background: optional (N, H, W, 3) uint8 RGB video frames drawn under the
            reconstruction instead of the demonstration's masks (which are then outlined
            on them in their roles' colours).
        frames_video: ``"gif"`` (``overlay.gif``), ``"mp4"`` (``overlay.mp4``) or None
            (no overlay).
        render_scale: ray cast at this fraction of the image size (then enlarged to it);
            None picks 1 unless the video exceeds :data:`RENDER_BUDGET` pixels.

    Returns:
        Picture name (``"overlay"``, ``"top_view"``, ``"trajectories"``) -> path written.

    Raises:
        ValueError: ``demo`` or ``background`` disagrees with ``recon`` in frame count,
            image size or intrinsics, or ``frames_video`` / ``render_scale`` is invalid.
    """
    check_picture_inputs(recon, demo, background)
    check_render_scale(render_scale)
    if frames_video is not None and frames_video not in VIDEO_FORMATS:
        raise ValueError(f"frames_video: expected one of {VIDEO_FORMATS} or None, got {frames_video!r}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {}
    if frames_video is not None:
        frames = overlay_frames(recon, demo, background=background, render_scale=render_scale)
        paths["overlay"] = write_video(out_dir / f"overlay.{frames_video}", frames, float(recon.fps))
    paths["top_view"] = save_figure(top_view_figure(recon), out_dir / "top_view.png")
    paths["trajectories"] = save_figure(trajectories_figure(recon, demo), out_dir / "trajectories.png")
    return paths


# --------------------------------------------------------------------------- overlay


# --------------------------------------------------------------------------- top view


# --------------------------------------------------------------------------- trajectories


# --------------------------------------------------------------------------- helpers


