"""A video of a MuJoCo replay where an offscreen renderer works, else a plain 3D plot of the paths."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np


def prefer_headless_gl() -> None:
    """Without a display, have MuJoCo render offscreen through EGL (unless ``MUJOCO_GL`` says
    otherwise). MuJoCo picks its GL backend when it is imported, so this does nothing once it
    is (switching later aborts the process in the renderer); where EGL is missing,
    :func:`record` falls back to a plot."""
    if "mujoco" not in sys.modules and not os.environ.get("DISPLAY"):
        os.environ.setdefault("MUJOCO_GL", "egl")


class _Recorder:
    """Collects offscreen MuJoCo frames (the ``video`` hook of :func:`replay_mujoco.simulate`)."""

    def __init__(self, lookat: np.ndarray, size: tuple[int, int] = (480, 640)):
        self.lookat = lookat
        self.size = size
        self.frames: list[np.ndarray] = []
        self.renderer = None

    def start(self, model):
        import mujoco

        model.vis.headlight.ambient[:] = 0.35
        model.vis.headlight.diffuse[:] = 0.6
        self.renderer = mujoco.Renderer(model, *self.size)
        self.camera = mujoco.MjvCamera()
        self.camera.lookat[:] = self.lookat
        self.camera.distance, self.camera.azimuth, self.camera.elevation = 1.1, -120.0, -30.0
        return self.renderer

    def frame(self, model, data) -> None:
        self.renderer.update_scene(data, self.camera)
        self.frames.append(self.renderer.render().copy())


VIDEO_FPS = 25.0  # [1/s] frames of the replay video
_offscreen = {"failed": False}  # MuJoCo aborts the process on a second try after its GL backend failed once


def record(plan, recon, result, out: Path) -> Path:
    """Write ``out/replay.mp4``, the whole plan replayed in MuJoCo and rendered offscreen, or,
    where no renderer works, ``out/replay.png`` (a 3D plot of the replayed paths)."""
    from warpskill.visual.media import write_video

    frames = None if _offscreen["failed"] else _render(plan, recon)
    if frames is None:
        return _plot(result.reconstruction, out / "replay.png")
    try:
        return write_video(out / "replay.mp4", frames, VIDEO_FPS)
    except OSError:  # no MP4 writer here
        return _plot(result.reconstruction, out / "replay.png")


def _render(plan, recon) -> np.ndarray | None:
    """(F, H, W, 3) frames of the whole plan at :data:`VIDEO_FPS`, or None without an offscreen renderer."""
    from warpskill.robot import replay_mujoco

    centre = np.vstack([recon.object_pos, recon.static_pos]).mean(axis=0) + np.array([0.0, 0.0, 0.05])
    recorder = _Recorder(centre)
    try:
        replay_mujoco.simulate(plan, recon, np.arange(0.0, plan.t[-1] + 1e-9, 1.0 / VIDEO_FPS), video=recorder)
    except Exception:  # noqa: BLE001 - MuJoCo raises various errors when no GL context can be made
        if recorder.renderer is None:
            _offscreen["failed"] = True
            return None
        raise
    finally:
        if recorder.renderer is not None:
            recorder.renderer.close()
    return np.stack(recorder.frames)


def _plot(replayed, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d")
    ax.plot(*replayed.hand_pos.T, label="gripper TCP")
    ax.plot(*replayed.object_pos.T, label="object centre")
    for corners in replayed.static_corners():
        ax.scatter(*corners.T, s=4, c="grey")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.legend()
    ax.set_title(f"{replayed.action}: replay")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
