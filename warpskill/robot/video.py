"""A video of a MuJoCo replay where an offscreen renderer works, else a plain 3D plot of the paths."""

from __future__ import annotations

from pathlib import Path

import numpy as np


class _Recorder:
    """Collects offscreen MuJoCo frames (the ``video`` hook of :func:`replay_mujoco.simulate`)."""

    def __init__(self, lookat: np.ndarray, size: tuple[int, int] = (480, 640)):
        self.lookat = lookat
        self.size = size
        self.frames: list[np.ndarray] = []
        self.renderer = None

    def start(self, model):
        import mujoco

        self.renderer = mujoco.Renderer(model, *self.size)
        self.camera = mujoco.MjvCamera()
        self.camera.lookat[:] = self.lookat
        self.camera.distance, self.camera.azimuth, self.camera.elevation = 1.4, -120.0, -25.0
        return self.renderer

    def frame(self, model, data) -> None:
        self.renderer.update_scene(data, self.camera)
        self.frames.append(self.renderer.render().copy())


def record(plan, recon, result, out: Path) -> Path:
    """Write ``out/replay.mp4`` (MuJoCo offscreen) or, failing that, ``out/replay.png`` (3D plot)."""
    from warpskill.robot import replay_mujoco

    try:
        recorder = _Recorder(recon.object_pos[0])
        times = np.arange(plan.start_time, plan.t[-1] + 1e-9, 1.0 / float(recon.fps))
        replay_mujoco.simulate(plan, recon, times, video=recorder)
        import imageio.v2 as imageio

        path = out / "replay.mp4"
        imageio.mimwrite(path, recorder.frames, fps=float(recon.fps))
        return path
    except Exception:  # noqa: BLE001 - no GL context, no ffmpeg: fall back to a plot
        return _plot(result.reconstruction, out / "replay.png")


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
