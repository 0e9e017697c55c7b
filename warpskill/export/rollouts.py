"""Successful rollouts of a skill in random layouts, filmed by fixed cameras for a dataset.

For each layout of :func:`~warpskill.export.layouts.layouts`: the Panda's plan
(:func:`warpskill.robot.retarget`), its MuJoCo replay judged by the action's criteria
(:func:`warpskill.robot.replay`), and, where it succeeds, the same run once more sampled at
the dataset's rate from the plan's start (home) to its end, with every camera rendered
offscreen (:class:`Episode`). The physics is deterministic, so the filmed run is the judged one.

The cameras (:data:`CAMERAS`) are fixed relative to the robot base, as cameras mounted on
its table: ``front`` looks at the workspace from the robot's front left (the replay video's
view), ``top`` from above.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

import numpy as np

from warpskill.contract.skill import Layout, LayoutError, Skill
from warpskill.export.layouts import layouts
from warpskill.robot import replay, replay_mujoco, retarget
from warpskill.robot.model import FINGER_JOINTS
from warpskill.robot.plan import PlanError, RobotPlan
from warpskill.robot.scene_config import load_scene_config

__all__ = ["CAMERAS", "TASKS", "Camera", "Episode", "film", "rollouts"]

TASKS: dict[str, str] = {
    "pull_left_to_right": "pull the object from left to right",
    "pull_right_to_left": "pull the object from right to left",
    "push_left_to_right": "push the object from left to right",
    "push_right_to_left": "push the object from right to left",
    "pick_up": "pick up the object",
    "put_behind": "put the object behind the box",
    "put_in_front_of": "put the object in front of the box",
    "put_next_to": "put the object next to the box",
    "put_onto": "put the object onto the box",
}
"""The task text of each action, as the dataset states it."""

STATE_NAMES = [f"panda_joint{i}" for i in range(1, 8)] + ["gripper_opening"]
"""``observation.state``: the simulated arm joints [rad] and finger distance [m]; ``action``: the commanded ones."""


@dataclasses.dataclass(frozen=True)
class Camera:
    """A MuJoCo free camera fixed relative to the robot base.

    Attributes:
        name: the feature is ``observation.images.<name>``.
        ahead: [m] the point looked at lies this far ahead of the base (base +x) ...
        height: [m] ... and this high above the table.
        distance: [m] from that point.
        azimuth: [deg] of the viewing direction about z, from the base's forward axis.
        elevation: [deg] of the viewing direction (negative: looking down).
    """

    name: str
    ahead: float
    height: float
    distance: float
    azimuth: float
    elevation: float

    def view(self, base: np.ndarray):
        """The ``mujoco.MjvCamera`` of this camera for a robot at ``base`` (4, 4)."""
        import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

        camera = mujoco.MjvCamera()
        camera.lookat[:] = base[:3, :3] @ np.array([self.ahead, 0.0, 0.0]) + base[:3, 3] + [0.0, 0.0, self.height]
        camera.distance = self.distance
        camera.azimuth = math.degrees(math.atan2(base[1, 0], base[0, 0])) + self.azimuth
        camera.elevation = self.elevation
        return camera


def _front() -> Camera:
    video = load_scene_config().video.camera
    return Camera("front", ahead=0.45, height=video.lookat_height, distance=1.5, azimuth=video.azimuth,
                  elevation=video.elevation)


CAMERAS: dict[str, Camera] = {
    "front": _front(),
    "top": Camera("top", ahead=0.4, height=0.0, distance=1.6, azimuth=0.0, elevation=-80.0),
}
"""The dataset's cameras by name."""


@dataclasses.dataclass
class Episode:
    """One filmed rollout.

    Attributes:
        layout: where it ran.
        state: (T, 8) simulated joints [rad] and finger distance [m] (:data:`STATE_NAMES`).
        action: (T, 8) the plan's commanded joints and finger distance at the same times.
        frames: camera name -> (T, H, W, 3) uint8 RGB.
        task: the task text.
    """

    layout: Layout
    state: np.ndarray
    action: np.ndarray
    frames: dict[str, np.ndarray]
    task: str


class _Filming:
    """The ``video`` hook of ``replay_mujoco.simulate``: renders every camera and records the joints."""

    def __init__(self, cameras: list[Camera], base: np.ndarray, size: tuple[int, int]):
        self.cameras, self.base, self.size = cameras, base, size
        self.frames: dict[str, list[np.ndarray]] = {camera.name: [] for camera in cameras}
        self.state: list[np.ndarray] = []
        self.renderer = None

    def start(self, model):
        import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

        model.vis.quality.offsamples = 0  # software GL: no multisampling, no shadow or reflection passes
        self.renderer = mujoco.Renderer(model, *self.size)
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self.views = [camera.view(self.base) for camera in self.cameras]
        self.arm = [model.joint(f"panda_joint{i}").qposadr[0] for i in range(1, 8)]
        self.fingers = [model.joint(name).qposadr[0] for name in FINGER_JOINTS]
        return self.renderer

    def frame(self, model, data) -> None:
        self.state.append(np.append(data.qpos[self.arm], data.qpos[self.fingers].sum()))
        for camera, view in zip(self.cameras, self.views):
            self.renderer.update_scene(data, view)
            self.frames[camera.name].append(self.renderer.render().copy())


def film(plan: RobotPlan, recon, *, fps: int, cameras: list[Camera], size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, dict]:
    """Run ``plan`` in MuJoCo from its start to its end at ``fps``, rendering ``cameras``.

    Returns:
        ``state`` (T, 8), ``action`` (T, 8) (the plan's command at the same times) and
        camera name -> (T, H, W, 3) uint8 frames.
    """
    times = np.arange(0.0, plan.t[-1] + 1e-9, 1.0 / fps)
    filming = _Filming(cameras, plan.base, size)
    try:
        replay_mujoco.simulate(plan, recon, times, video=filming)
    finally:
        if filming.renderer is not None:
            filming.renderer.close()
    action = np.column_stack([*(np.interp(times, plan.t, plan.q[:, i]) for i in range(7)),
                              np.interp(times, plan.t, plan.gripper)])
    frames = {name: np.stack(images) for name, images in filming.frames.items()}
    return np.asarray(filming.state), action, frames


@dataclasses.dataclass
class Attempt:
    """One layout tried: its plan and replay, or why it failed (``reason`` empty on success)."""

    layout: Layout
    reason: str
    episode: Episode | None = None


def rollouts(skill: Skill, *, fps: int, cameras: list[Camera], size: tuple[int, int], seed: int = 0,
             ) -> Iterator[Attempt]:
    """Endless attempts of ``skill`` in the random layouts of ``seed``; successful ones carry their :class:`Episode`."""
    task = TASKS[skill.action]
    for layout in layouts(skill, seed=seed):
        recon = skill.apply(layout)
        try:
            plan = retarget(skill, layout=layout)
        except (PlanError, LayoutError) as error:
            yield Attempt(layout, f"plan: {error}")
            continue
        result = replay(plan, recon)
        if not result.success:
            failed = [name for name, ok in result.evaluation.checks.items() if not ok]
            yield Attempt(layout, f"replay fails {', '.join(failed)}")
            continue
        state, action, frames = film(plan, recon, fps=fps, cameras=cameras, size=size)
        yield Attempt(layout, "", Episode(layout, state, action, frames, task))
