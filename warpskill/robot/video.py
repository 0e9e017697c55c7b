"""A video of a MuJoCo replay where an offscreen renderer works, else a plain 3D plot of the paths.

The frame size, rate, camera and lights are the ``[video]`` table of
``assets/robot_scene.toml`` (:func:`~warpskill.robot.scene_config.load_scene_config`): the
camera looks at a point between the robot base and the scene from the robot's front left, so the
whole arm, the table and the cuboids are in view; a headlight and directional lights
(added by :func:`~warpskill.robot.replay_mujoco.build_model`) light them. The object, the
static cuboids and the arm wear the colours of the pictures (:mod:`warpskill.media`'s palette).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from warpskill.media import GRIPPER_COLOR, OBJECT_COLOR, ROBOT_COLOR, STATIC_COLOR, figure, rgb, save_figure, write_mp4
from warpskill.robot import replay_mujoco
from warpskill.robot.scene_config import CameraConfig, load_scene_config


def prefer_headless_gl() -> None:
    """Without a display, have MuJoCo render offscreen through EGL (unless ``MUJOCO_GL`` says
    otherwise). MuJoCo picks its GL backend when it is imported, so this does nothing once it
    is (switching later aborts the process in the renderer); where EGL is missing,
    :func:`record` falls back to a plot."""
    if "mujoco" not in sys.modules and not os.environ.get("DISPLAY"):
        os.environ.setdefault("MUJOCO_GL", "egl")


def camera_view(base: np.ndarray, recon, camera: CameraConfig | None = None) -> dict:
    """The video camera for a robot at ``base`` in the scene of ``recon``.

    Args:
        base: (4, 4) pose of the robot base in the world.
        recon: the reconstruction (the object's path and the static cuboids).
        camera: the camera settings; default: the scene description's.

    Returns:
        ``lookat`` (3,) [m], ``distance`` [m], ``azimuth``, ``elevation`` [deg] of a MuJoCo
        free camera (world frame).
    """
    camera = camera or load_scene_config().video.camera
    xy = np.concatenate([recon.object_pos[:, :2], recon.static_pos[:, :2]], 0)
    centre = 0.5 * (xy.min(0) + xy.max(0))
    lookat_xy = (1.0 - camera.lookat_blend) * base[:2, 3] + camera.lookat_blend * centre
    yaw = np.degrees(np.arctan2(base[1, 0], base[0, 0]))
    return {
        "lookat": np.array([lookat_xy[0], lookat_xy[1], camera.lookat_height]),
        "distance": camera.distance,
        "azimuth": yaw + camera.azimuth,
        "elevation": camera.elevation,
    }


class _Recorder:
    """Collects offscreen MuJoCo frames (the ``video`` hook of :func:`replay_mujoco.simulate`)."""

    def __init__(self, view: dict, size: tuple[int, int] | None = None):
        video = load_scene_config().video
        self.view = view
        self.size = size or (video.height, video.width)
        self.frames: list[np.ndarray] = []
        self.renderer = None

    def start(self, model):
        import mujoco  # the optional extra "robot"

        _paint(model)
        self.renderer = mujoco.Renderer(model, *self.size)
        self.camera = mujoco.MjvCamera()
        self.camera.lookat[:] = self.view["lookat"]
        self.camera.distance = self.view["distance"]
        self.camera.azimuth, self.camera.elevation = self.view["azimuth"], self.view["elevation"]
        return self.renderer

    def frame(self, model, data) -> None:
        self.renderer.update_scene(data, self.camera)
        self.frames.append(self.renderer.render().copy())


_offscreen = {"failed": False}  # MuJoCo aborts the process on a second try after its GL backend failed once


def record(plan, recon, result, out: Path) -> Path:
    """Write ``out/replay.mp4``, the whole plan replayed in MuJoCo and rendered offscreen, or,
    where no renderer works, ``out/replay.png`` (a 3D plot of the replayed paths)."""

    frames = None if _offscreen["failed"] else _render(plan, recon)
    if frames is None:
        return _plot(result.reconstruction, out / "replay.png")
    try:
        return write_mp4(out / "replay.mp4", frames, load_scene_config().video.fps)
    except OSError:  # no MP4 writer here
        return _plot(result.reconstruction, out / "replay.png")


def _paint(model) -> None:
    """Colour the compiled scene ``model`` as the pictures do: the object, the static cuboids,
    the arm and the gripper (rendering only: colours change no physics)."""
    for g in range(model.ngeom):
        name = model.geom(g).name
        body = model.body(model.geom_bodyid[g]).name
        if body == replay_mujoco.OBJECT_BODY:
            color = OBJECT_COLOR
        elif name.startswith("static"):
            color = STATIC_COLOR
        elif body.startswith("panda_"):
            color = GRIPPER_COLOR if "finger" in body or body == "panda_hand" else ROBOT_COLOR
        else:
            continue
        model.geom_rgba[g] = (*rgb(color), 1.0)


def _render(plan, recon) -> np.ndarray | None:
    """(F, H, W, 3) frames of the whole plan at the video's rate (``video.fps``), or None without an offscreen renderer."""
    recorder = _Recorder(camera_view(plan.base, recon))
    try:
        times = np.arange(0.0, plan.t[-1] + 1e-9, 1.0 / load_scene_config().video.fps)
        replay_mujoco.simulate(plan, recon, times, video=recorder)
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
    fig = figure(6.0, 5.0)
    ax = fig.add_subplot(projection="3d")
    ax.plot(*replayed.hand_pos.T, color=rgb(GRIPPER_COLOR), label="gripper TCP")
    ax.plot(*replayed.object_pos.T, color=rgb(OBJECT_COLOR), label="object centre")
    for corners in replayed.static_corners():
        ax.scatter(*corners.T, s=4, color=rgb(STATIC_COLOR))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.legend()
    ax.set_title(f"{replayed.action}: replay")
    return save_figure(fig, path)
